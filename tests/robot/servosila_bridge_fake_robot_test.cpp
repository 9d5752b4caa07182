// The bridge against a scripted fake robot on loopback, without wmd: poses go to a sink that keeps them in memory.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "clients/robot/servosila_bridge.h"
#include "clients/robot/servosila_protocol.h"
#include "tests/robot/servosila_bridge_test_helpers.h"

namespace wm::robot {
namespace {

using namespace bridge_test_helpers;

// ---- against the fake robot ----

TEST(ServosilaBridgeTest, SendsFiveControlPacketsASecondWithEveryButtonReleased) {
  FakeRobot robot;
  LogLines log;
  Bridge bridge(test_options(robot.port(), log));
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  bridge.set_velocity(0.3, 0.0);
  const std::size_t before = robot.received().size();
  std::this_thread::sleep_for(milliseconds(1000));
  const auto received = robot.received();
  const std::size_t in_one_second = received.size() - before;
  EXPECT_GE(in_one_second, 4u);
  EXPECT_LE(in_one_second, 7u);
  for (const auto& r : received) {
    for (const auto button : r.packet.buttons) ASSERT_EQ(button, 0);
    ASSERT_EQ(r.packet.video_bit_rate, 0.0);
  }
  const AxisCommand last = axes_of(received.back().packet);
  EXPECT_EQ(last.drive, -static_cast<int>(std::lround(0.3 * kDriveUnitsPerMps))) << "forward is negative";
  EXPECT_EQ(last.turn, 0);
}

TEST(ServosilaBridgeTest, WatchdogStopsWhenTheRobotGoesQuietAndHoldsTheStopUntilTheNextCommand) {
  FakeRobot robot;
  LogLines log;
  BridgeOptions options = test_options(robot.port(), log);
  options.watchdog_s = 0.3;
  robot.set_answering(false);
  Bridge bridge(options);
  // Commands before the link is up are not sent, not even once it is up.
  bridge.set_velocity(0.3, 0.0);
  robot.set_answering(true);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  std::this_thread::sleep_for(milliseconds(250));
  EXPECT_TRUE(is_stop(robot.last()->packet));
  bridge.set_velocity(0.3, 0.0);
  ASSERT_TRUE(robot_gets_stop(robot, false));

  robot.set_answering(false);
  const Clock::time_point quiet = Clock::now();
  ASSERT_TRUE(wait_until([&] { return is_stop(robot.last()->packet); }, milliseconds(1000)));
  const double after_s = std::chrono::duration<double>(robot.last()->at - quiet).count();
  EXPECT_GT(after_s, 0.25);
  EXPECT_LT(after_s, 0.6) << "the watchdog time (0.3 s) after the last telemetry";
  EXPECT_EQ(bridge.stats().watchdog_trips, 1u);
  EXPECT_TRUE(bridge.status().watchdog_tripped);
  EXPECT_EQ(log.count("watchdog"), 1u);

  robot.set_answering(true);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(1000)));
  std::this_thread::sleep_for(milliseconds(500));
  const auto received = robot.received();
  EXPECT_TRUE(is_stop(received.back().packet)) << "the stop is held after the link is back";
  EXPECT_TRUE(bridge.status().stop_latched);
  bridge.set_velocity(0.3, 0.0);
  EXPECT_TRUE(robot_gets_stop(robot, false));
  EXPECT_FALSE(bridge.status().stop_latched);
}

TEST(ServosilaBridgeTest, MalformedTelemetryAndNaNCommandsAreCountedAndIgnored) {
  FakeRobot robot;
  LogLines log;
  Bridge bridge(test_options(robot.port(), log));
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  bridge.set_velocity(0.3, 0.0);
  ASSERT_TRUE(robot_gets_stop(robot, false));

  std::vector<std::uint8_t> truncated(100, 0);
  truncated[0] = 2;
  std::vector<std::uint8_t> oversized(300, 0);
  oversized[0] = 2;
  std::vector<std::uint8_t> unknown(kTelemetryPacketSize, 0);
  unknown[0] = 9;
  std::vector<std::uint8_t> too_many(kTelemetryPacketSize, 0);
  too_many[0] = 2;
  too_many[9] = 11;
  std::vector<std::uint8_t> video(1000, 0);
  video[0] = 4;
  const auto control = encode_control(ControlPacket{});
  for (int i = 0; i < 3; ++i) {
    robot.send_raw(truncated);
    robot.send_raw(oversized);
    robot.send_raw(unknown);
    robot.send_raw(too_many);
    robot.send_raw(video);
    robot.send_raw(control);
  }
  robot.send_raw(std::span<const std::uint8_t>{});
  ASSERT_TRUE(wait_until([&] { return bridge.stats().unexpected_frame_type == 3; }, milliseconds(1000)));
  const BridgeStats stats = bridge.stats();
  EXPECT_EQ(stats.truncated, 4u);
  EXPECT_EQ(stats.oversized, 3u);
  EXPECT_EQ(stats.unknown_frame_type, 3u);
  EXPECT_EQ(stats.too_many_motors, 3u);
  EXPECT_EQ(stats.video_frames, 3u);
  EXPECT_EQ(log.count("ignored"), 5u) << "one line per kind (rate-limited):\n" << log.all();
  EXPECT_TRUE(bridge.status().link_up);
  EXPECT_FALSE(is_stop(robot.last()->packet)) << "bad packets do not change the command";

  bridge.set_velocity(std::nan(""), 0.1);
  EXPECT_TRUE(robot_gets_stop(robot, true));
  bridge.set_velocity(0.3, 0.0);
  EXPECT_TRUE(robot_gets_stop(robot, false));
  bridge.set_velocity(0.2, INFINITY);
  EXPECT_TRUE(robot_gets_stop(robot, true));
  std::this_thread::sleep_for(milliseconds(300));
  EXPECT_TRUE(is_stop(robot.last()->packet));
  EXPECT_EQ(bridge.stats().commands_rejected, 2u);
}

TEST(ServosilaBridgeTest, WithoutTrackRecordsTheOdometryIntegratesTheCommandedVelocity) {
  FakeRobot robot;
  robot.set_motors({});  // as the seed reports for the real Engineer's chassis
  LogLines log;
  Bridge bridge(test_options(robot.port(), log));
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  EXPECT_EQ(bridge.status().odometry, OdometrySource::commanded);
  EXPECT_EQ(log.count("commanded velocity"), 1u) << log.all();
  const Clock::time_point start = Clock::now();
  const ConversionResult sent = bridge.set_velocity(0.3, 0.0);
  std::this_thread::sleep_for(milliseconds(700));
  bridge.set_velocity(0.0, 0.0);
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  ASSERT_TRUE(bridge.wait_until_stopped(milliseconds(500)));
  const OdometryPose pose = bridge.status().report.pose;
  EXPECT_NEAR(pose.x_m, sent.sent.linear_mps * elapsed, 0.01);
  EXPECT_EQ(pose.y_m, 0.0);
  EXPECT_GT(pose.covariance(0, 0), 0.0);
}

TEST(ServosilaBridgeTest, TracksForcedWithoutTrackRecordsNeverClaimsAStop) {
  FakeRobot robot;
  robot.set_motors({track(7, 0)});
  LogLines log;
  BridgeOptions options = test_options(robot.port(), log);
  options.odometry = OdometrySource::tracks;
  Bridge bridge(options);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  EXPECT_FALSE(bridge.wait_until_stopped(milliseconds(200)));
  EXPECT_GT(bridge.stats().odometry_track_missing, 0u);
  EXPECT_TRUE(bridge.status().report.moving);
}

TEST(ServosilaBridgeTest, APoseSinkThatFailsIsCountedAndTheBridgeCarriesOn) {
  class FailingSink : public PoseSink {
   public:
    void publish(const PoseReport&) override { throw std::runtime_error("server down"); }
  };
  FakeRobot robot;
  LogLines log;
  Bridge bridge(test_options(robot.port(), log), std::make_shared<FailingSink>());
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  ASSERT_TRUE(wait_until([&] { return bridge.stats().publish_errors >= 3; }, milliseconds(1000)));
  EXPECT_EQ(log.count("server down"), 1u);
  bridge.set_velocity(0.3, 0.0);
  EXPECT_TRUE(robot_gets_stop(robot, false));
}

TEST(ServosilaBridgeTest, InvalidOptionsAreRefused) {
  LogLines log;
  BridgeOptions o = test_options(10000, log);
  o.watchdog_s = 0.0;
  EXPECT_THROW(Bridge{o}, std::invalid_argument);
  o = test_options(10000, log);
  o.units.max_linear_mps = 0.1;  // below the 0.2 m/s minimum
  EXPECT_THROW(Bridge{o}, std::invalid_argument);
  o = test_options(10000, log);
  o.command_timeout_s = 1e10;  // to_duration would overflow
  EXPECT_THROW(Bridge{o}, std::invalid_argument);
  o = test_options(10000, log);
  o.command_timeout_s = 3601.0;
  EXPECT_THROW(Bridge{o}, std::invalid_argument);
  o = test_options(10000, log);
  o.robot_host = "no-such-host.invalid";
  EXPECT_THROW(Bridge{o}, std::runtime_error);
}

}  // namespace
}  // namespace wm::robot
