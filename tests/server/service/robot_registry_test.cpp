// The robot registry on its own: statuses and their thresholds, the track's spacing and length, event pacing.
#include "server/service/robot_registry.h"

#include <gtest/gtest.h>

namespace wm::service {
namespace {

RobotPose at(double x, double y, double theta, double t) { return RobotPose{x, y, theta, std::nullopt, t, t, ""}; }

TEST(RobotRegistryTest, StatusFollowsTheLastTimeHeardFromAndAnAnnouncedStop) {
  RobotRegistry registry;
  registry.on_scan("r1", "laser", at(0, 0, 0, 1000.0));
  const auto robot = *registry.find("r1");
  EXPECT_EQ(registry.status(robot, 1004.9), RobotStatus::alive);
  EXPECT_EQ(registry.status(robot, 1005.1), RobotStatus::stale);
  registry.on_pose("r1", at(0, 0, 0, 1006.0), /*stopped=*/true);
  EXPECT_EQ(registry.status(*registry.find("r1"), 1006.0), RobotStatus::stopped);
  EXPECT_EQ(registry.status(*registry.find("r1"), 9999.0), RobotStatus::stopped) << "stopped is said, not guessed";
  registry.on_primitives("r1", 1010.0);
  EXPECT_EQ(registry.status(*registry.find("r1"), 1010.0), RobotStatus::alive) << "it sent again";
  const auto counted = *registry.find("r1");
  EXPECT_EQ(counted.scans.at("laser"), 1);
  EXPECT_EQ(counted.poses, 1);
  EXPECT_EQ(counted.primitives, 1);
  EXPECT_DOUBLE_EQ(counted.first_seen_unix_s, 1000.0);
  EXPECT_DOUBLE_EQ(counted.last_seen_unix_s, 1010.0);
}

TEST(RobotRegistryTest, TheTrackKeepsPosesApartAndOnlyTheNewest) {
  RobotOptions options;
  options.track_points = 10;
  RobotRegistry registry(options);
  for (int i = 0; i < 100; ++i) registry.on_scan("r1", "laser", at(0.01 * i, 0, 0, 100.0 + i));  // 1 cm steps
  auto robot = *registry.find("r1");
  ASSERT_GE(robot.track.size(), 2u);
  for (std::size_t i = 1; i < robot.track.size(); ++i)
    EXPECT_GE(robot.track[i].x - robot.track[i - 1].x, options.track_spacing_m - 1e-12);
  for (int i = 0; i < 100; ++i) registry.on_scan("r1", "laser", at(1.0 + i, 0, 0, 300.0 + i));  // 1 m steps
  robot = *registry.find("r1");
  EXPECT_EQ(robot.track.size(), 10u);
  EXPECT_DOUBLE_EQ(robot.track.back().x, 100.0);
  EXPECT_DOUBLE_EQ(robot.pose->x, 100.0);
  EXPECT_EQ(robot.pose->via, "scan:laser");
  registry.on_scan("r1", "laser", at(100.0, 0, 0.5, 500.0));  // turning on the spot counts too
  EXPECT_DOUBLE_EQ(registry.find("r1")->track.back().theta, 0.5);
}

TEST(RobotRegistryTest, EventsComeAtMostFiveASecondPerRobotButAStatusChangeAlwaysComes) {
  RobotRegistry registry;
  int events = 0;
  for (int i = 0; i < 100; ++i) events += registry.on_scan("r1", "laser", at(i, 0, 0, 1000.0 + 0.01 * i)) ? 1 : 0;
  EXPECT_EQ(events, 5);  // one second of scans at 100 Hz
  EXPECT_TRUE(registry.on_pose("r1", at(0, 0, 0, 1000.995), true)) << "stopping is an event however soon";
  EXPECT_TRUE(registry.on_scan("r2", "sonar", at(0, 0, 0, 1000.995))) << "another robot has its own pace";
}

}  // namespace
}  // namespace wm::service
