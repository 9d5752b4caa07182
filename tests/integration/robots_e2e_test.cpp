// The robots resource through the running wmd: a replayed log makes its robot, a reported pose moves it, and both
// come back after a restart.
#include <cmath>

#include "e2e_fixture.h"
#include "logs/carmen_log_reader.h"

namespace wm::testing {
namespace {

class RobotsTest : public ServerFixture {};

TEST_F(RobotsTest, ARobotIsWhereItsLastScanWasAndWhereItSaysAndComesBackAfterARestart) {
  const auto log = std::filesystem::path(WM_TEST_DATA_DIR) / "carmen/intel-corrected-excerpt.log.gz";
  const auto replay = run_command(wmctl(server_->url(), "replay " + log.string() + " --source robot-7"));
  ASSERT_EQ(replay.status, 0) << replay.output;
  logs::CarmenLogReader reader(log);
  std::size_t scans = 0;
  fusion::Pose2D last;
  for (auto scan = reader.next(); scan; scan = reader.next(), ++scans) last = scan->scan.sensor_pose;

  auto robot = get_json("/api/v1/robots/robot-7");
  EXPECT_EQ(robot["status"], "alive");
  EXPECT_EQ(robot["scans"]["laser"], scans);
  EXPECT_EQ(robot["pose"]["source"], "scan:laser");
  // Where the last scan was placed: its posted pose, aligned to the map's lines by a few cm and a fraction of a degree.
  EXPECT_NEAR(robot["pose"]["x"].get<double>(), last.x_m, 0.10);
  EXPECT_NEAR(robot["pose"]["y"].get<double>(), last.y_m, 0.10);
  EXPECT_NEAR(robot["pose"]["theta"].get<double>(), last.theta_rad, 0.02);
  EXPECT_EQ(robot["pose"]["cov"][0][0], 0.03 * 0.03) << "wmctl replay's pose sigma";
  EXPECT_GT(robot["track"].size(), 1u);
  const auto listed_by_wmctl = run_command(wmctl(server_->url(), "robots"));
  EXPECT_EQ(listed_by_wmctl.status, 0);
  EXPECT_NE(listed_by_wmctl.output.find("robot-7"), std::string::npos) << listed_by_wmctl.output;
  EXPECT_NE(listed_by_wmctl.output.find(std::to_string(scans) + " laser scans"), std::string::npos)
      << listed_by_wmctl.output;

  EventClient events(server_->port());
  send_json("POST", "/api/v1/primitives", {{"source", "robot-7"}, {"segments", {{{"p0", {1, 1}}, {"p1", {1, 3}}}}}});
  send_json("PUT", "/api/v1/robots/robot-7/pose", {{"x", 2.0}, {"y", 3.0}, {"theta", 0.5}, {"state", "stopped"}});
  auto event = events.next_of("robot");
  if (event["robot"]["status"] != "stopped") event = events.next_of("robot");  // the primitives' event came first
  EXPECT_EQ(event["robot"]["id"], "robot-7");
  EXPECT_EQ(event["robot"]["status"], "stopped") << "a status change is always an event";
  EXPECT_DOUBLE_EQ(event["robot"]["pose"]["x"].get<double>(), 2.0);
  robot = get_json("/api/v1/robots/robot-7");
  EXPECT_EQ(robot["primitives"], 1);
  EXPECT_EQ(robot["poses"], 1);
  EXPECT_EQ(robot["status"], "stopped");
  EXPECT_EQ(robot["pose"]["source"], "reported");
  const auto listed = get_json("/api/v1/robots");
  ASSERT_EQ(listed["robots"].size(), 1u);

  restart();
  const auto again = get_json("/api/v1/robots/robot-7");
  EXPECT_EQ(again["scans"]["laser"], scans);
  EXPECT_EQ(again["primitives"], 1);
  EXPECT_EQ(again["poses"], 1);
  EXPECT_EQ(again["status"], "stopped");
  EXPECT_DOUBLE_EQ(again["pose"]["x"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(again["pose"]["theta"].get<double>(), 0.5);
  // The journal has the time each request arrived; the live registry the time it was committed (ms later).
  EXPECT_NEAR(again["first_seen"].get<double>(), robot["first_seen"].get<double>(), 1.0);
  EXPECT_EQ(call("GET", "/api/v1/robots/nobody").status, 404);
}

}  // namespace
}  // namespace wm::testing
