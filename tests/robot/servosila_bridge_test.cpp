// The bridge against the simulated robot and against a scripted fake robot, on loopback, without wmd: poses go to
// a sink that keeps them in memory.
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

namespace wm::robot {
namespace {

namespace asio = boost::asio;
using udp = asio::ip::udp;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

/// Calls `done` every 5 ms until it holds or `timeout` passes; true when it held.
bool wait_until(const std::function<bool()>& done, Clock::duration timeout) {
  const Clock::time_point deadline = Clock::now() + timeout;
  for (;;) {
    if (done()) return true;
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(milliseconds(5));
  }
}

/// Keeps every report in memory.
class CollectingSink : public PoseSink {
 public:
  void publish(const PoseReport& report) override {
    const std::lock_guard lock(mutex_);
    reports_.push_back(report);
  }
  std::vector<PoseReport> reports() const {
    const std::lock_guard lock(mutex_);
    return reports_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<PoseReport> reports_;
};

/// Log lines, kept for the test to count.
class LogLines {
 public:
  std::function<void(const std::string&)> sink() {
    return [this](const std::string& line) {
      const std::lock_guard lock(mutex_);
      lines_.push_back(line);
    };
  }
  std::size_t count(const std::string& part) const {
    const std::lock_guard lock(mutex_);
    std::size_t n = 0;
    for (const auto& line : lines_) n += line.find(part) != std::string::npos ? 1 : 0;
    return n;
  }
  std::string all() const {
    const std::lock_guard lock(mutex_);
    std::string text;
    for (const auto& line : lines_) text += line + "\n";
    return text;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::string> lines_;
};

BridgeOptions test_options(std::uint16_t robot_port, LogLines& log) {
  BridgeOptions o;
  o.robot_host = "127.0.0.1";
  o.robot_port = robot_port;
  o.watchdog_s = 0.5;
  o.report_period_s = 0.05;
  o.log = log.sink();
  return o;
}

SimOptions sim_options() {
  SimOptions o;
  o.telemetry_period_s = 0.05;
  o.watchdog_s = 10.0;  // so that only a stop packet can stop it
  return o;
}

MotorRecord track(std::uint8_t id, std::uint32_t position) {
  MotorRecord m;
  m.device_id = id;
  m.position = position;
  return m;
}

bool moving(const ServosilaSim& sim) {
  const Velocity v = sim.truth().velocity;
  return v.linear_mps != 0.0 || v.angular_radps != 0.0;
}

/// A robot played by the test: records the control packets it gets and, while answering, sends telemetry every
/// 20 ms to whoever sent the last one (with the track records it is given).
class FakeRobot {
 public:
  struct Received {
    Clock::time_point at;
    ControlPacket packet;
  };

  FakeRobot() : socket_(io_, udp::endpoint(asio::ip::address_v4::loopback(), 0)) {
    socket_.non_blocking(true);
    thread_ = std::thread([this] { run(); });
  }
  ~FakeRobot() {
    quit_ = true;
    thread_.join();
  }

  std::uint16_t port() const { return socket_.local_endpoint().port(); }
  void set_answering(bool answering) { answering_ = answering; }
  void set_motors(std::vector<MotorRecord> motors) {
    const std::lock_guard lock(mutex_);
    motors_ = std::move(motors);
  }
  std::vector<Received> received() const {
    const std::lock_guard lock(mutex_);
    return received_;
  }
  std::optional<Received> last() const {
    const std::lock_guard lock(mutex_);
    if (received_.empty()) return std::nullopt;
    return received_.back();
  }
  /// Sends raw bytes from the robot's socket to the operator (the bridge).
  void send_raw(std::span<const std::uint8_t> bytes) {
    const std::lock_guard lock(mutex_);
    socket_.send_to(asio::buffer(bytes.data(), bytes.size()), *operator_);
  }
  bool heard_from_operator() const {
    const std::lock_guard lock(mutex_);
    return operator_.has_value();
  }

 private:
  void run() {
    std::array<std::uint8_t, 2048> buffer{};
    Clock::time_point next_telemetry = Clock::now();
    while (!quit_) {
      for (;;) {
        udp::endpoint from;
        boost::system::error_code ec;
        const std::size_t n = socket_.receive_from(asio::buffer(buffer), from, 0, ec);
        if (ec) break;
        const std::lock_guard lock(mutex_);
        received_.push_back({Clock::now(), decode_control(std::span<const std::uint8_t>(buffer.data(), n))});
        operator_ = from;
      }
      if (Clock::now() >= next_telemetry) {
        next_telemetry += milliseconds(20);
        const std::lock_guard lock(mutex_);
        if (answering_ && operator_) {
          TelemetryPacket packet;
          packet.tick = ++tick_;
          packet.motors = motors_;
          const auto bytes = encode_telemetry(packet);
          boost::system::error_code ec;
          socket_.send_to(asio::buffer(bytes), *operator_, 0, ec);
        }
      }
      std::this_thread::sleep_for(milliseconds(2));
    }
  }

  asio::io_context io_;
  udp::socket socket_;
  std::thread thread_;
  std::atomic<bool> quit_{false};
  std::atomic<bool> answering_{true};
  mutable std::mutex mutex_;
  std::vector<MotorRecord> motors_ = {track(0, 1000), track(1, 2000)};
  std::vector<Received> received_;
  std::optional<udp::endpoint> operator_;
  std::uint64_t tick_ = 0;
};

AxisCommand axes_of(const ControlPacket& packet) { return VelocityConverter().read_axes(packet); }
bool is_stop(const ControlPacket& packet) {
  const AxisCommand a = axes_of(packet);
  return a.drive == 0 && a.turn == 0;
}

/// Waits (up to 300 ms) until the last control packet the robot got is a stop (or is not).
bool robot_gets_stop(const FakeRobot& robot, bool stop) {
  return wait_until(
      [&] {
        const auto last = robot.last();
        return last && is_stop(last->packet) == stop;
      },
      milliseconds(300));
}

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
  o.robot_host = "no-such-host.invalid";
  EXPECT_THROW(Bridge{o}, std::runtime_error);
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
