#include "clients/robot/servosila_sim.h"

#include <gtest/gtest.h>

#include <array>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/udp.hpp>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <span>
#include <thread>
#include <vector>

#include "clients/robot/odometry.h"
#include "clients/robot/servosila_protocol.h"
#include "clients/robot/servosila_units.h"

namespace wm::robot {
namespace {

namespace asio = boost::asio;
using udp = asio::ip::udp;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

/// The operator's side in one thread: a non-blocking UDP socket that sends control packets to the simulator and
/// drains the telemetry that comes back.
class Operator {
 public:
  explicit Operator(std::uint16_t robot_port)
      : socket_(io_, udp::endpoint(asio::ip::address_v4::loopback(), 0)),
        robot_(asio::ip::address_v4::loopback(), robot_port) {
    socket_.non_blocking(true);
  }

  void send(const AxisCommand& axes) {
    ControlPacket packet;
    converter_.write_axes(axes, packet);
    send_raw(encode_control(packet));
  }
  void send_velocity(double linear_mps, double angular_radps) {
    send(converter_.convert(linear_mps, angular_radps).axes);
  }
  template <typename Bytes>
  void send_raw(const Bytes& bytes) {
    socket_.send_to(asio::buffer(bytes.data(), bytes.size()), robot_);
  }

  /// Decodes every datagram waiting on the socket.
  std::vector<TelemetryPacket> poll() {
    std::vector<TelemetryPacket> packets;
    for (;;) {
      udp::endpoint from;
      boost::system::error_code ec;
      const std::size_t n = socket_.receive_from(asio::buffer(buffer_), from, 0, ec);
      if (ec == asio::error::would_block || ec == asio::error::try_again) break;
      if (ec) throw boost::system::system_error(ec);
      packets.push_back(decode_telemetry(std::span<const std::uint8_t>(buffer_.data(), n)));
    }
    return packets;
  }

 private:
  asio::io_context io_;
  udp::socket socket_;
  udp::endpoint robot_;
  VelocityConverter converter_;
  std::array<std::uint8_t, 2048> buffer_{};
};

/// Calls `each` every 5 ms until `done` holds or `timeout` passes; true when `done` held.
bool wait_until(const std::function<bool()>& done, Clock::duration timeout, const std::function<void()>& each = {}) {
  const Clock::time_point deadline = Clock::now() + timeout;
  for (;;) {
    if (each) each();
    if (done()) return true;
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(milliseconds(5));
  }
}

bool moving(const ServosilaSim& sim) {
  const Velocity v = sim.truth().velocity;
  return v.linear_mps != 0.0 || v.angular_radps != 0.0;
}

SimOptions fast_options() {
  SimOptions options;
  options.telemetry_period_s = 0.05;
  options.watchdog_s = 0.5;
  return options;
}

/// Sends stops until the first telemetry packet gives the odometry its reference (the robot answers only once it
/// has heard from us, and the counts must be taken before it moves), drives at (v, ω) for `duration` with a
/// control packet every 20 ms, sends stops until the robot stands, and feeds two more telemetry packets (the
/// second certainly sent after the stop) to the odometry.
void drive_and_stop(ServosilaSim& sim, Operator& op, DiffDriveOdometry& odometry, double v, double w,
                    Clock::duration duration) {
  bool started = false;
  const auto feed = [&] {
    for (const TelemetryPacket& p : op.poll()) started |= odometry.update(p) == OdometryUpdate::started;
  };
  ASSERT_TRUE(wait_until([&] { return started; }, milliseconds(2000),
                         [&] {
                           op.send_velocity(0.0, 0.0);
                           feed();
                         }));
  const Clock::time_point end = Clock::now() + duration;
  Clock::time_point next_send = Clock::now();
  wait_until([&] { return Clock::now() >= end; }, duration + milliseconds(500),
             [&] {
               if (Clock::now() >= next_send) {
                 op.send_velocity(v, w);
                 next_send += milliseconds(20);
               }
               feed();
             });
  ASSERT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(2000),
                         [&] {
                           op.send_velocity(0.0, 0.0);
                           feed();
                         }));
  int after_stop = 0;
  ASSERT_TRUE(wait_until([&] { return after_stop >= 2; }, milliseconds(2000),
                         [&] {
                           for (const TelemetryPacket& p : op.poll()) {
                             odometry.update(p);
                             ++after_stop;
                           }
                         }));
}

TEST(ServosilaSimTest, OdometryFromTelemetryMatchesTruthAfterOneSecondForward) {
  SimOptions options = fast_options();
  options.initial_position = 4294967295u - 500u;  // the counters wrap after 5 cm
  ServosilaSim sim(options);
  Operator op(sim.port());
  DiffDriveOdometry odometry(options.tracks);
  drive_and_stop(sim, op, odometry, 0.3, 0.0, milliseconds(1000));

  const SimTruth truth = sim.truth();
  EXPECT_GT(truth.x_m, 0.2);  // about 0.3 m; the exact distance depends on the scheduling
  EXPECT_LT(truth.x_m, 0.45);
  EXPECT_NEAR(truth.y_m, 0.0, 1e-9);
  EXPECT_NEAR(odometry.pose().x_m, truth.x_m, 1e-3);
  EXPECT_NEAR(odometry.pose().y_m, truth.y_m, 1e-3);
  EXPECT_NEAR(odometry.pose().theta_rad, truth.theta_rad, 1e-3);
  EXPECT_GT(odometry.pose().covariance(0, 0), 0.0);
  EXPECT_FALSE(truth.watchdog_stopped);
  EXPECT_GT(sim.stats().telemetry_sent, 10u);
}

TEST(ServosilaSimTest, OdometryFromTelemetryMatchesTruthOnAnArc) {
  ServosilaSim sim(fast_options());
  Operator op(sim.port());
  DiffDriveOdometry odometry;
  drive_and_stop(sim, op, odometry, 0.3, 0.6, milliseconds(800));

  const SimTruth truth = sim.truth();
  EXPECT_GT(truth.theta_rad, 0.3);  // about 0.48 rad to the left
  EXPECT_GT(truth.y_m, 0.02);
  EXPECT_NEAR(odometry.pose().x_m, truth.x_m, 5e-3);
  EXPECT_NEAR(odometry.pose().y_m, truth.y_m, 5e-3);
  EXPECT_NEAR(odometry.pose().theta_rad, truth.theta_rad, 5e-3);
}

TEST(ServosilaSimTest, StopsOnZeroCommandDespiteTwentyPercentLossAndReordering) {
  SimOptions options = fast_options();
  options.watchdog_s = 30.0;  // only the zero command may stop it
  options.loss_probability = 0.2;
  options.reorder_probability = 0.2;
  options.random_seed = 42;
  ServosilaSim sim(options);
  Operator op(sim.port());

  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(2000), [&] { op.send_velocity(0.3, 0.0); }));
  wait_until([] { return false; }, milliseconds(300), [&] { op.send_velocity(0.3, 0.0); });
  // Zero commands at the operator's real rate, five a second.
  Clock::time_point next_send = Clock::now();
  const auto send_stops = [&] {
    if (Clock::now() >= next_send) {
      op.send_velocity(0.0, 0.0);
      next_send += milliseconds(200);
    }
  };
  ASSERT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(3000), send_stops));
  // A reordered forward packet could restart it once; the next zero command must stop it again for good.
  wait_until([] { return false; }, milliseconds(600), send_stops);
  ASSERT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(1000), send_stops));
  const SimTruth stopped = sim.truth();
  std::this_thread::sleep_for(milliseconds(100));
  EXPECT_EQ(sim.truth().x_m, stopped.x_m);
  EXPECT_FALSE(stopped.watchdog_stopped);
  const SimStats stats = sim.stats();
  EXPECT_GT(stats.control_lost + stats.telemetry_lost, 0u);  // about 100 datagrams at 20 %
}

TEST(ServosilaSimTest, WatchdogStopsTheRobotWhenControlGoesQuiet) {
  SimOptions options = fast_options();
  options.watchdog_s = 0.4;
  ServosilaSim sim(options);
  Operator op(sim.port());

  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(2000), [&] { op.send_velocity(0.3, 0.0); }));
  Clock::time_point last_send = Clock::now();
  wait_until([] { return false; }, milliseconds(600),
             [&] {
               op.send_velocity(0.3, 0.0);
               last_send = Clock::now();
             });
  ASSERT_TRUE(moving(sim));  // driven for longer than the watchdog: it does not trip while packets arrive
  ASSERT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(2000)));
  const double quiet_s = std::chrono::duration<double>(Clock::now() - last_send).count();
  EXPECT_GE(quiet_s, 0.35);
  EXPECT_LT(quiet_s, 1.5);
  const SimTruth truth = sim.truth();
  EXPECT_TRUE(truth.watchdog_stopped);
  EXPECT_EQ(sim.stats().watchdog_stops, 1u);
  std::this_thread::sleep_for(milliseconds(100));
  EXPECT_EQ(sim.truth().x_m, truth.x_m);
}

TEST(ServosilaSimTest, StallsBelowTheMinimumSpeed) {
  ServosilaSim sim(fast_options());
  Operator op(sim.port());
  // 0.1 m/s sent raw (7202 units), bypassing the converter's raise to 0.2 m/s: the motors do not turn.
  const AxisCommand slow{static_cast<std::int16_t>(-std::lround(0.1 * kDriveUnitsPerMps)), 0};
  ASSERT_TRUE(
      wait_until([&] { return sim.stats().control_received >= 5; }, milliseconds(2000), [&] { op.send(slow); }));
  EXPECT_FALSE(moving(sim));
  EXPECT_EQ(sim.truth().x_m, 0.0);
  // The converter's 0.05 m/s becomes the minimum 0.2 m/s, which moves it.
  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(2000), [&] { op.send_velocity(0.05, 0.0); }));
  EXPECT_NEAR(sim.truth().velocity.linear_mps, 0.2, 1e-4);
}

TEST(ServosilaSimTest, IgnoresMalformedDatagramsAndAnswersTheLastSender) {
  ServosilaSim sim(fast_options());
  Operator a(sim.port());
  Operator b(sim.port());
  std::vector<std::uint8_t> short_packet(56, 0x00);
  short_packet[0] = 0x01;
  std::vector<std::uint8_t> long_packet(58, 0x00);
  long_packet[0] = 0x01;
  std::vector<std::uint8_t> unknown_type(57, 0x00);
  unknown_type[0] = 0x03;
  std::vector<std::uint8_t> telemetry_type(57, 0x00);
  telemetry_type[0] = 0x02;
  std::vector<std::uint8_t> empty;
  for (const auto* bytes : {&short_packet, &long_packet, &unknown_type, &telemetry_type, &empty}) a.send_raw(*bytes);
  ASSERT_TRUE(wait_until([&] { return sim.stats().control_rejected >= 5; }, milliseconds(2000)));
  EXPECT_EQ(sim.stats().control_rejected, 5u);
  EXPECT_EQ(sim.stats().control_received, 0u);
  // No valid packet yet: nobody to send telemetry to.
  std::this_thread::sleep_for(milliseconds(150));
  EXPECT_TRUE(a.poll().empty());
  EXPECT_EQ(sim.stats().telemetry_sent, 0u);

  a.send_velocity(0.0, 0.0);
  std::size_t received_by_a = 0;
  ASSERT_TRUE(
      wait_until([&] { return received_by_a > 0; }, milliseconds(2000), [&] { received_by_a += a.poll().size(); }));
  b.send_velocity(0.0, 0.0);
  std::size_t received_by_b = 0;
  ASSERT_TRUE(
      wait_until([&] { return received_by_b > 0; }, milliseconds(2000), [&] { received_by_b += b.poll().size(); }));
  a.poll();
  std::this_thread::sleep_for(milliseconds(150));
  EXPECT_TRUE(a.poll().empty());  // telemetry now goes to b only
}

TEST(ServosilaSimTest, RejectsInvalidOptions) {
  const auto invalid = [](auto mutate) {
    SimOptions o;
    mutate(o);
    EXPECT_THROW(ServosilaSim{o}, std::invalid_argument);
  };
  invalid([](SimOptions& o) { o.telemetry_period_s = 0.0; });
  invalid([](SimOptions& o) { o.physics_period_s = -1.0; });
  invalid([](SimOptions& o) { o.watchdog_s = std::nan(""); });
  invalid([](SimOptions& o) { o.loss_probability = 1.5; });
  invalid([](SimOptions& o) { o.reorder_probability = -0.1; });
  invalid([](SimOptions& o) { o.tracks.right_track_id = o.tracks.left_track_id; });
  invalid([](SimOptions& o) { o.units.drive_axis = o.units.turn_axis; });
  ServosilaSim sim(fast_options());
  EXPECT_THROW(sim.set_loss_probability(2.0), std::invalid_argument);
  EXPECT_NO_THROW(sim.set_reorder_probability(0.5));
}

}  // namespace
}  // namespace wm::robot
