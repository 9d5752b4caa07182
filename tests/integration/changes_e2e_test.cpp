// The change workflow against the real wmd over loopback HTTP, with a token: a room ray-cast by a robot driving
// laps, a plan with one wall the building does not have; then the list, hostile requests against the new routes
// (ids of every shape, oversized and malformed bodies, twenty clients accepting the same change at once), and wmctl.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "e2e_fixture.h"
#include "tools/raycast/raycast.h"

namespace wm::testing {
namespace {

class ChangesE2eTest : public ServerFixture {
 protected:
  void SetUp() override {
    extra_args_ = {"--token", "s3cret"};
    start();
  }

  client::HttpResult authorised(const std::string& method, const std::string& target, const std::string& body = {}) {
    return client_->request(method, target, body, "application/json", "s3cret");
  }

  // A 10 × 6 m room; the plan also has an inner wall at x = 5 from y = 0 to 3 that was demolished.
  void drive_through_the_room() {
    const std::vector<raycast::PlanLine> room{
        {{0, 0}, {10, 0}}, {{10, 0}, {10, 6}}, {{10, 6}, {0, 6}}, {{0, 6}, {0, 0}}};
    json plan = {{"name", "room"}, {"units", "m"}, {"objects", json::array()}};
    const std::vector<std::pair<std::string, raycast::PlanLine>> walls{
        {"south", room[0]}, {"east", room[1]}, {"north", room[2]}, {"west", room[3]}, {"inner", {{5, 0}, {5, 3}}}};
    for (const auto& [id, line] : walls)
      plan["objects"].push_back({{"id", id},
                                 {"kind", "wall"},
                                 {"attributes", {"solid"}},
                                 {"pose", {{"x", 0}, {"y", 0}, {"theta", 0}}},
                                 {"segments", {{{line.p0.x(), line.p0.y()}, {line.p1.x(), line.p1.y()}}}}});
    ASSERT_EQ(authorised("PUT", "/api/v1/floorplan", plan.dump()).status, 200);
    raycast::DriveOptions options;
    options.step_m = 0.25;
    options.beams = 360;
    options.max_range_m = 15;
    const std::vector<std::vector<Eigen::Vector2d>> route{{{1.5, 1.5}, {8.5, 1.5}, {8.5, 4.5}, {1.5, 4.5}, {1.5, 1.5}}};
    for (const auto& scan : raycast::simulate_scans(room, route, options)) {
      json ranges = json::array();
      for (const double r : scan.ranges_m) ranges.push_back(std::isfinite(r) ? json(r) : json(nullptr));
      const json body = {
          {"sensor", "laser"},
          {"source", "robot-1"},
          {"stamp", 1.0},
          {"pose", {{"x", scan.sensor_pose.x_m}, {"y", scan.sensor_pose.y_m}, {"theta", scan.sensor_pose.theta_rad}}},
          {"angle_min", scan.angle_min_rad},
          {"angle_increment", scan.angle_increment_rad},
          {"ranges", ranges},
          {"range_min", scan.range_min_m},
          {"range_max", scan.range_max_m},
          {"sigma_range", 0.01}};
      ASSERT_EQ(authorised("POST", "/api/v1/scans", body.dump()).status, 200);
    }
  }

  json changes() { return get_json("/api/v1/changes")["changes"]; }
};

TEST_F(ChangesE2eTest, DemolishedWallIsListedAcceptedOnceAndUndone) {
  drive_through_the_room();
  auto list = changes();
  std::string id;
  for (const auto& c : list)
    if (c["key"] == "missing:inner/0") id = c["id"];
  ASSERT_FALSE(id.empty()) << list.dump(2);
  for (const auto& c : list) EXPECT_NE(c["kind"], "wall_partly_missing") << c.dump();  // the room's walls stand
  // wmctl explain says how much was seen through, by how many beams.
  auto r = run_command(wmctl(server_->url(), "explain inner"));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("beams passed through it"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("verdict missing (wall_missing)"), std::string::npos) << r.output;
  r = run_command(wmctl(server_->url(), "changes"));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find(id), std::string::npos) << r.output;

  const auto count_lines = [](const std::string& dxf) {
    std::size_t n = 0;
    for (auto at = dxf.find("\nLINE"); at != std::string::npos; at = dxf.find("\nLINE", at + 1)) ++n;
    return n;
  };
  const auto dxf_before = call("GET", "/api/v1/map?format=dxf");
  ASSERT_EQ(dxf_before.status, 200);
  // Without the token nothing happens.
  EXPECT_EQ(call("POST", "/api/v1/changes/" + id + "/accept").status, 401);
  // Twenty clients accept the same change at once: one applies it, the others find it no longer listed.
  std::atomic<int> accepted{0}, not_found{0}, other{0};
  std::vector<std::thread> clients;
  for (int i = 0; i < 20; ++i)
    clients.emplace_back([&] {
      const auto answer = authorised("POST", "/api/v1/changes/" + id + "/accept");
      (answer.status == 200 ? accepted : answer.status == 404 ? not_found : other)++;
    });
  for (auto& t : clients) t.join();
  EXPECT_EQ(accepted, 1);
  EXPECT_EQ(not_found, 19);
  EXPECT_EQ(other, 0);
  const auto plan = get_json("/api/v1/floorplan");
  for (const auto& o : plan["objects"]) EXPECT_NE(o["id"], "inner");
  // The as-built drawing goes back to the architect without the wall.
  const auto dxf = call("GET", "/api/v1/map?format=dxf");
  EXPECT_EQ(dxf.status, 200);
  EXPECT_EQ(count_lines(dxf.body) + 1, count_lines(dxf_before.body));
  const auto decisions = get_json("/api/v1/decisions?limit=10000")["decisions"];
  EXPECT_EQ(std::count_if(decisions.begin(), decisions.end(), [](const json& d) { return d["action"] == "accept"; }),
            1);
  // Undo through wmctl: the wall is back and missing again.
  r = run_command(wmctl(server_->url(), "--token s3cret changes undo"));
  EXPECT_EQ(r.status, 0) << r.output;
  list = changes();
  EXPECT_TRUE(std::any_of(list.begin(), list.end(), [&](const json& c) { return c["id"] == id; })) << list.dump();
}

TEST_F(ChangesE2eTest, HostileRequestsGetClearErrorsAndChangeNothing) {
  drive_through_the_room();
  const auto before = get_json("/api/v1/floorplan");
  const auto version = get_json("/api/v1/health")["version"];
  const std::string long_id(10000, 'c');
  for (const std::string& target : std::vector<std::string>{
           "/api/v1/changes/" + long_id + "/accept", std::string("/api/v1/changes/%00/accept"),
           std::string("/api/v1/changes/c%2F..%2F..%2Fx/accept"), std::string("/api/v1/changes/../accept"),
           std::string("/api/v1/changes//accept"), std::string("/api/v1/changes/c0123456789ab/accept"),
           std::string("/api/v1/changes/c0123456789ab/delete"), std::string("/api/v1/changes/undo/accept")}) {
    const auto answer = authorised("POST", target);
    // 431: a target of 10 000 characters is refused with the request line, before any route is looked at.
    EXPECT_TRUE(answer.status == 404 || answer.status == 400 || answer.status == 405 || answer.status == 431)
        << target.substr(0, 80) << " -> " << answer.status << " " << answer.body.substr(0, 200);
  }
  std::string id = changes().at(0)["id"];
  for (const std::string& body : std::vector<std::string>{
           std::string("{"), std::string("[]"), std::string("{\"source\": 1}"),
           std::string("{\"source\": \"a\", \"extra\": 1}"),
           std::string("{\"source\": \"") + std::string(1000, 'x') + "\"}", std::string(64 * 1024, '[')}) {
    const auto answer = authorised("POST", "/api/v1/changes/" + id + "/reject", body);
    EXPECT_EQ(answer.status, 400) << body.substr(0, 60) << " -> " << answer.body.substr(0, 200);
  }
  EXPECT_EQ(get_json("/api/v1/floorplan"), before);
  EXPECT_EQ(get_json("/api/v1/health")["version"], version);
  // Undo with nothing decided: 409.
  EXPECT_EQ(authorised("POST", "/api/v1/changes/undo").status, 409);
  // The server still serves.
  EXPECT_EQ(call("GET", "/api/v1/health").status, 200);
}

}  // namespace
}  // namespace wm::testing
