// The bridge against the simulated robot on loopback, without wmd (poses go to a sink that keeps them in memory),
// and its pieces.
#include "clients/robot/servosila_bridge.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/udp.hpp>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "clients/robot/servosila_protocol.h"
#include "clients/robot/servosila_sim.h"
#include "clients/robot/servosila_units.h"
#include "tests/robot/servosila_bridge_test_helpers.h"

namespace wm::robot {
namespace {

using namespace bridge_test_helpers;

// ---- against the simulator ----

TEST(ServosilaBridgeTest, CommandsReachTheSimulatorAndTheOdometryFollowsIt) {
  ServosilaSim sim(sim_options());
  LogLines log;
  auto sink = std::make_shared<CollectingSink>();
  auto bridge = std::make_unique<Bridge>(test_options(sim.port(), log), sink);
  ASSERT_TRUE(bridge->wait_for_link(milliseconds(2000))) << log.all();
  EXPECT_EQ(bridge->status().odometry, OdometrySource::tracks);

  const ConversionResult sent = bridge->set_velocity(0.3, 0.5);
  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(500)));
  EXPECT_NEAR(sim.truth().velocity.linear_mps, sent.sent.linear_mps, 1e-9);
  EXPECT_NEAR(sim.truth().velocity.angular_radps, sent.sent.angular_radps, 1e-9);
  std::this_thread::sleep_for(milliseconds(800));
  EXPECT_TRUE(bridge->status().report.moving);

  bridge->set_velocity(0.0, 0.0);
  EXPECT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(200)));
  ASSERT_TRUE(bridge->wait_until_stopped(milliseconds(1000))) << log.all();
  const SimTruth truth = sim.truth();
  const BridgeStatus status = bridge->status();
  EXPECT_FALSE(status.report.moving);
  EXPECT_NEAR(status.report.pose.x_m, truth.x_m, 0.002);
  EXPECT_NEAR(status.report.pose.y_m, truth.y_m, 0.002);
  EXPECT_NEAR(status.report.pose.theta_rad, truth.theta_rad, 0.002);
  EXPECT_GT(truth.x_m, 0.2);
  EXPECT_GT(status.report.pose.covariance(0, 0), 0.0);

  bridge.reset();
  const auto reports = sink->reports();
  ASSERT_GE(reports.size(), 10u) << "about 20 a second for 1.5 s";
  EXPECT_TRUE(reports.front().moving || reports[1].moving || reports[2].moving);
  EXPECT_FALSE(reports.back().moving) << "the final report says stopped";
  EXPECT_NEAR(reports.back().pose.x_m, truth.x_m, 0.002);
  EXPECT_FALSE(sim.truth().watchdog_stopped);
  EXPECT_EQ(sim.stats().control_rejected, 0u);
}

TEST(ServosilaBridgeTest, DestroyingTheBridgeStopsTheRobotWithABurstOfStops) {
  ServosilaSim sim(sim_options());
  LogLines log;
  auto bridge = std::make_unique<Bridge>(test_options(sim.port(), log));
  ASSERT_TRUE(bridge->wait_for_link(milliseconds(2000)));
  bridge->set_velocity(0.3, 0.0);
  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(500)));
  const std::uint64_t received_before = sim.stats().control_received;

  std::atomic<bool> destroyed{false};
  std::thread destroyer([&] {
    bridge.reset();
    destroyed = true;
  });
  const Clock::time_point start = Clock::now();
  const bool stopped = wait_until([&] { return !moving(sim); }, milliseconds(1000));
  const auto delay = std::chrono::duration_cast<milliseconds>(Clock::now() - start);
  destroyer.join();
  EXPECT_TRUE(stopped);
  EXPECT_LT(delay.count(), 150) << "the first stop goes out at once";
  EXPECT_FALSE(sim.truth().watchdog_stopped) << "a stop packet, not the simulator's watchdog";
  EXPECT_GE(sim.stats().control_received - received_before, 5u) << "the burst: 5 stops over 200 ms";
}

TEST(ServosilaBridgeTest, AfterHaltEveryCommandIsIgnoredAndOnlyStopsAreSent) {
  ServosilaSim sim(sim_options());
  LogLines log;
  Bridge bridge(test_options(sim.port(), log));
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  bridge.set_velocity(0.3, 0.0);
  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(500)));
  bridge.halt();
  EXPECT_FALSE(moving(sim));
  bridge.set_velocity(0.3, 0.0);
  std::this_thread::sleep_for(milliseconds(300));
  EXPECT_FALSE(moving(sim));
  EXPECT_EQ(bridge.stats().commands_ignored, 1u);
  EXPECT_TRUE(bridge.status().halted);
}

TEST(ServosilaBridgeTest, WithTwentyPercentLossAndReorderingTheRobotStillStopsOnAZeroCommand) {
  SimOptions options = sim_options();
  options.loss_probability = 0.2;
  options.reorder_probability = 0.1;
  options.random_seed = 7;
  ServosilaSim sim(options);
  LogLines log;
  BridgeOptions bridge_options = test_options(sim.port(), log);
  bridge_options.watchdog_s = 1.0;  // 20 telemetry periods: a run of lost packets is not a dead link
  Bridge bridge(bridge_options);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  for (int run = 0; run < 4; ++run) {
    SCOPED_TRACE("run " + std::to_string(run));
    bridge.set_velocity(run % 2 == 0 ? 0.3 : -0.3, 0.4);
    ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(1500)));
    std::this_thread::sleep_for(milliseconds(300));
    bridge.set_velocity(0.0, 0.0);
    // Every control packet from now on is a stop; a reordered older command may move the robot once more, until
    // the next stop.
    std::this_thread::sleep_for(milliseconds(400));
    ASSERT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(1500)));
    ASSERT_TRUE(bridge.wait_until_stopped(milliseconds(2000))) << log.all();
    EXPECT_FALSE(moving(sim));
    const SimTruth truth = sim.truth();
    const OdometryPose pose = bridge.status().report.pose;
    EXPECT_NEAR(pose.x_m, truth.x_m, 0.003);
    EXPECT_NEAR(pose.y_m, truth.y_m, 0.003);
    EXPECT_NEAR(pose.theta_rad, truth.theta_rad, 0.003);
  }
  EXPECT_FALSE(sim.truth().watchdog_stopped);
  EXPECT_GT(sim.stats().control_lost, 0u);
  EXPECT_GT(sim.stats().telemetry_lost, 0u);
  EXPECT_EQ(bridge.stats().watchdog_trips, 0u) << log.all();
}

TEST(ServosilaBridgeTest, WhenTheSimulatorStopsAnsweringTheWatchdogTripsAndOnlyStopsReachItAfterwards) {
  ServosilaSim sim(sim_options());  // its own watchdog is 10 s: it keeps driving while cut off
  LogLines log;
  BridgeOptions options = test_options(sim.port(), log);
  options.watchdog_s = 0.3;
  Bridge bridge(options);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  bridge.set_velocity(0.3, 0.0);
  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(500)));

  sim.set_loss_probability(1.0);  // nothing in, nothing out
  ASSERT_TRUE(wait_until([&] { return bridge.stats().watchdog_trips == 1; }, milliseconds(1000))) << log.all();
  EXPECT_TRUE(moving(sim)) << "cut off, the simulator has heard nothing yet";
  sim.set_loss_probability(0.0);
  // The first packet that gets through is a stop, and the stop is held although the link is back.
  ASSERT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(500)));
  EXPECT_FALSE(sim.truth().watchdog_stopped);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(1000)));
  std::this_thread::sleep_for(milliseconds(300));
  EXPECT_FALSE(moving(sim));
  EXPECT_TRUE(bridge.wait_until_stopped(milliseconds(1000)));
}

TEST(ServosilaBridgeTest, DatagramsFromAnotherAddressOrPortAreCountedAndIgnored) {
  ServosilaSim sim(sim_options());
  LogLines log;
  Bridge bridge(test_options(sim.port(), log));
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000)));
  ASSERT_TRUE(bridge.wait_until_stopped(milliseconds(1000)));
  const OdometryPose before = bridge.status().report.pose;
  const std::uint64_t telemetry_before = bridge.stats().telemetry_received;

  // Valid telemetry whose counts would throw the pose 0.5 m forward, from an impostor.
  TelemetryPacket fake;
  fake.tick = 1u << 30;
  fake.motors = {track(0, 5000), track(1, 5000)};
  const auto bytes = encode_telemetry(fake);
  asio::io_context io;
  const udp::endpoint bridge_endpoint(asio::ip::address_v4::loopback(), bridge.local_port());
  udp::socket other_port(io, udp::endpoint(asio::ip::address_v4::loopback(), 0));
  std::uint64_t sent = 0;
  for (int i = 0; i < 30; ++i, ++sent) other_port.send_to(asio::buffer(bytes), bridge_endpoint);
  // Another address: all of 127/8 is loopback on Linux; elsewhere this part is skipped.
  udp::socket other_address(io);
  boost::system::error_code ec;
  other_address.open(udp::v4());
  other_address.bind(udp::endpoint(asio::ip::make_address("127.0.0.2"), 0), ec);
  if (!ec) {
    for (int i = 0; i < 3; ++i, ++sent) other_address.send_to(asio::buffer(bytes), bridge_endpoint);
  }
  ASSERT_TRUE(wait_until([&] { return bridge.stats().foreign == sent; }, milliseconds(1000)))
      << bridge.stats().foreign << " of " << sent;
  std::this_thread::sleep_for(milliseconds(100));
  const OdometryPose after = bridge.status().report.pose;
  EXPECT_EQ(after.x_m, before.x_m);
  EXPECT_EQ(after.y_m, before.y_m);
  EXPECT_GT(bridge.stats().telemetry_received, telemetry_before) << "the robot's own telemetry still counts";
  EXPECT_EQ(bridge.stats().odometry_jumps, 0u);
  EXPECT_LE(log.count("not the robot"), 2u) << "rate-limited:\n" << log.all();
  EXPECT_GE(log.count("not the robot"), 1u);
}

// ---- the pieces ----

TEST(ServosilaBridgeTest, PoseReportIsTheBodyWmdExpects) {
  PoseReport report;
  report.pose.x_m = 1.5;
  report.pose.y_m = -2.0;
  report.pose.theta_rad = 0.25;
  report.pose.covariance << 0.01, 0.002, 0.0, 0.002, 0.02, 0.001, 0.0, 0.001, 0.03;
  report.moving = false;
  report.stamp_unix_s = 1.7e9;
  const auto body = nlohmann::json::parse(pose_report_json(report));
  EXPECT_EQ(body["x"], 1.5);
  EXPECT_EQ(body["y"], -2.0);
  EXPECT_EQ(body["theta"], 0.25);
  EXPECT_EQ(body["cov"][0][1], 0.002);
  EXPECT_EQ(body["cov"][1][0], 0.002);
  EXPECT_EQ(body["cov"][2][2], 0.03);
  EXPECT_EQ(body["stamp"], 1.7e9);
  EXPECT_EQ(body["state"], "stopped");
  report.moving = true;
  EXPECT_EQ(nlohmann::json::parse(pose_report_json(report))["state"], "moving");
  EXPECT_EQ(body.size(), 6u);
}

TEST(ServosilaBridgeTest, HostAndPortAndRobotIds) {
  EXPECT_EQ(parse_host_port("10.42.0.1", 10000).port, 10000);
  EXPECT_EQ(parse_host_port("10.42.0.1:2424", 10000).host, "10.42.0.1");
  EXPECT_EQ(parse_host_port("10.42.0.1:2424", 10000).port, 2424);
  EXPECT_EQ(parse_host_port("robot.local:9", 1).host, "robot.local");
  EXPECT_EQ(parse_host_port("[::1]:10001", 1).host, "::1");
  EXPECT_EQ(parse_host_port("[::1]:10001", 1).port, 10001);
  EXPECT_EQ(parse_host_port("fe80::1", 7).host, "fe80::1");
  EXPECT_EQ(parse_host_port("fe80::1", 7).port, 7);
  EXPECT_THROW(parse_host_port("", 1), std::invalid_argument);
  EXPECT_THROW(parse_host_port(":5", 1), std::invalid_argument);
  EXPECT_THROW(parse_host_port("host:", 1), std::invalid_argument);
  EXPECT_THROW(parse_host_port("host:0", 1), std::invalid_argument);
  EXPECT_THROW(parse_host_port("host:65536", 1), std::invalid_argument);
  EXPECT_THROW(parse_host_port("host:12x", 1), std::invalid_argument);
  EXPECT_THROW(parse_host_port("[::1", 1), std::invalid_argument);
  EXPECT_TRUE(valid_robot_id("servosila-1.lab:a_b"));
  EXPECT_FALSE(valid_robot_id(""));
  EXPECT_FALSE(valid_robot_id("a/b"));
  EXPECT_FALSE(valid_robot_id(std::string(129, 'a')));
  EXPECT_THROW(HttpPoseSink("http://127.0.0.1:1", "bad id"), std::invalid_argument);
}

}  // namespace
}  // namespace wm::robot
