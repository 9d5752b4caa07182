#include "clients/robot/servosila_sim.h"

#include <array>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/udp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <numbers>
#include <optional>
#include <random>
#include <stdexcept>
#include <thread>

namespace wm::robot {

namespace asio = boost::asio;
using udp = asio::ip::udp;
using Clock = std::chrono::steady_clock;

namespace {

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument("ServosilaSim: " + message);
}

bool positive_finite(double v) { return std::isfinite(v) && v > 0.0; }
bool probability(double p) { return std::isfinite(p) && p >= 0.0 && p <= 1.0; }

void validate(const SimOptions& o) {
  require(positive_finite(o.telemetry_period_s), "telemetry_period_s must be finite and > 0");
  require(positive_finite(o.physics_period_s), "physics_period_s must be finite and > 0");
  require(positive_finite(o.watchdog_s), "watchdog_s must be finite and > 0");
  require(probability(o.loss_probability), "loss_probability must be in [0, 1]");
  require(probability(o.reorder_probability), "reorder_probability must be in [0, 1]");
  const OdometryOptions& t = o.tracks;
  require(t.left_track_id != t.right_track_id, "track ids must differ");
  require(positive_finite(t.position_units_per_m), "tracks.position_units_per_m must be finite and > 0");
  require(positive_finite(t.track_width_m), "tracks.track_width_m must be finite and > 0");
  require(t.left_sign == 1 || t.left_sign == -1, "tracks.left_sign must be +1 or -1");
  require(t.right_sign == 1 || t.right_sign == -1, "tracks.right_sign must be +1 or -1");
  require(t.position_bits >= 1 && t.position_bits <= 32, "tracks.position_bits must be in 1..32");
}

double normalize_angle(double a) {
  a = std::remainder(a, 2.0 * std::numbers::pi);
  return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

std::int16_t saturate_int16(double v) {
  const double r = std::round(v);
  if (!(r > std::numeric_limits<std::int16_t>::min())) return std::numeric_limits<std::int16_t>::min();
  if (r > std::numeric_limits<std::int16_t>::max()) return std::numeric_limits<std::int16_t>::max();
  return static_cast<std::int16_t>(r);
}

Clock::duration to_duration(double seconds) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

}  // namespace

struct ServosilaSim::Impl {
  explicit Impl(const SimOptions& o)
      : options(o),
        converter(o.units),
        socket(io, udp::endpoint(asio::ip::make_address(o.bind_address), o.port)),
        port(socket.local_endpoint().port()),
        physics_timer(io),
        telemetry_timer(io),
        rng(o.random_seed),
        loss_probability(o.loss_probability),
        reorder_probability(o.reorder_probability) {}

  void start() {
    last_step = Clock::now();
    start_receive();
    schedule_physics(last_step);
    schedule_telemetry(last_step);
    thread = std::thread([this] { io.run(); });
  }

  void stop() {
    io.stop();
    if (thread.joinable()) thread.join();
  }

  bool chance(double p) { return p > 0.0 && std::bernoulli_distribution(p)(rng); }

  void start_receive() {
    socket.async_receive_from(asio::buffer(rx_buffer), rx_from, [this](boost::system::error_code ec, std::size_t n) {
      if (ec == asio::error::operation_aborted) return;
      if (!ec) on_datagram(std::span<const std::uint8_t>(rx_buffer.data(), n), rx_from);
      start_receive();
    });
  }

  /// Loss happens on the wire, before the robot sees the bytes; then decoding; then possible reordering.
  void on_datagram(std::span<const std::uint8_t> bytes, const udp::endpoint& from) {
    const std::lock_guard lock(mutex);
    if (chance(loss_probability)) {
      ++stats.control_lost;
      return;
    }
    ControlPacket packet;
    try {
      packet = decode_control(bytes);
    } catch (const ProtocolError&) {
      ++stats.control_rejected;
      return;
    }
    const Velocity commanded = robot_velocity(converter.read_axes(packet));
    if (!held_control && chance(reorder_probability)) {
      held_control = HeldControl{commanded, from};
      ++stats.control_reordered;
      return;
    }
    apply(commanded, from);
    if (held_control) {
      apply(held_control->velocity, held_control->from);  // the older packet arrives last
      held_control.reset();
    }
  }

  /// The velocity the robot's motors produce for these axes: none below the minimum magnitudes.
  Velocity robot_velocity(const AxisCommand& axes) const {
    const Velocity v = converter.to_velocity(axes);
    const bool drive_stalls = std::abs(int{axes.drive}) < converter.min_drive_units();
    const bool turn_stalls = std::abs(int{axes.turn}) < converter.min_turn_units();
    return Velocity{drive_stalls ? 0.0 : v.linear_mps, turn_stalls ? 0.0 : v.angular_radps};
  }

  void apply(const Velocity& commanded, const udp::endpoint& from) {
    ++stats.control_received;
    truth.velocity = commanded;
    truth.watchdog_stopped = false;
    last_control = Clock::now();
    operator_endpoint = from;
  }

  void schedule_physics(Clock::time_point previous) {
    physics_timer.expires_at(previous + to_duration(options.physics_period_s));
    physics_timer.async_wait([this](boost::system::error_code ec) {
      if (ec) return;
      step();
      schedule_physics(physics_timer.expiry());
    });
  }

  void step() {
    const std::lock_guard lock(mutex);
    const Clock::time_point now = Clock::now();
    const double dt = std::chrono::duration<double>(now - last_step).count();
    last_step = now;
    ++ticks;
    const bool moving = truth.velocity.linear_mps != 0.0 || truth.velocity.angular_radps != 0.0;
    if (moving && (!last_control || now - *last_control > to_duration(options.watchdog_s))) {
      truth.velocity = Velocity{};
      truth.watchdog_stopped = true;
      ++stats.watchdog_stops;
    }
    const double v = truth.velocity.linear_mps;
    const double w = truth.velocity.angular_radps;
    // Exact unicycle motion over dt (an arc, or a segment when ω = 0).
    const double theta = truth.theta_rad;
    if (std::abs(w) < 1e-12) {
      truth.x_m += v * dt * std::cos(theta);
      truth.y_m += v * dt * std::sin(theta);
    } else {
      truth.x_m += v / w * (std::sin(theta + w * dt) - std::sin(theta));
      truth.y_m -= v / w * (std::cos(theta + w * dt) - std::cos(theta));
    }
    truth.theta_rad = normalize_angle(theta + w * dt);
    const double half_width = 0.5 * options.tracks.track_width_m;
    truth.left_track_m += (v - w * half_width) * dt;
    truth.right_track_m += (v + w * half_width) * dt;
  }

  void schedule_telemetry(Clock::time_point previous) {
    telemetry_timer.expires_at(previous + to_duration(options.telemetry_period_s));
    telemetry_timer.async_wait([this](boost::system::error_code ec) {
      if (ec) return;
      send_telemetry();
      schedule_telemetry(telemetry_timer.expiry());
    });
  }

  std::uint32_t counts(double track_m, int sign) const {
    const OdometryOptions& t = options.tracks;
    const auto travelled = static_cast<std::int64_t>(std::llround(sign * track_m * t.position_units_per_m));
    const std::uint64_t mask = (std::uint64_t{1} << t.position_bits) - 1;
    return static_cast<std::uint32_t>(
        (std::uint64_t{options.initial_position} + static_cast<std::uint64_t>(travelled)) & mask);
  }

  MotorRecord track_record(std::uint8_t id, double track_m, int sign, double speed_mps) const {
    MotorRecord m;
    m.device_id = id;
    m.device_state = 1;    // the protocol does not define states; 1 marks "running" in this simulator
    m.operation_mode = 1;  // likewise: speed control
    m.position = counts(track_m, sign);
    m.position_command = m.position;
    // The protocol gives the speed field no unit: the simulator reports the track's speed in the drive axis's
    // scale (72 021.7 per m/s), positive when the count grows.
    m.speed = saturate_int16(sign * speed_mps * options.units.drive_units_per_mps);
    m.speed_command = m.speed;
    // The amps field has no unit either: the simulator reports 1000 per m/s of track speed, a stand-in for the
    // load a real motor would show. A raised fault sets the flag and counts once on every record.
    m.amps = saturate_int16(std::abs(speed_mps) * 1000.0);
    m.fault_detected = fault ? 1 : 0;
    m.faults_counter = faults;
    return m;
  }

  void send_telemetry() {
    const std::lock_guard lock(mutex);
    if (!operator_endpoint) return;
    const double half_width = 0.5 * options.tracks.track_width_m;
    const double v = truth.velocity.linear_mps;
    const double w = truth.velocity.angular_radps;
    TelemetryPacket packet;
    packet.tick = ticks;
    packet.motors.push_back(
        track_record(options.tracks.left_track_id, truth.left_track_m, options.tracks.left_sign, v - w * half_width));
    packet.motors.push_back(track_record(options.tracks.right_track_id, truth.right_track_m, options.tracks.right_sign,
                                         v + w * half_width));
    const auto bytes = encode_telemetry(packet);
    if (chance(loss_probability)) {
      ++stats.telemetry_lost;
      return;
    }
    if (!held_telemetry && chance(reorder_probability)) {
      held_telemetry = HeldTelemetry{bytes, *operator_endpoint};
      ++stats.telemetry_reordered;
      return;
    }
    send(bytes, *operator_endpoint);
    if (held_telemetry) {
      send(held_telemetry->bytes, held_telemetry->to);
      held_telemetry.reset();
    }
  }

  void send(const std::array<std::uint8_t, kTelemetryPacketSize>& bytes, const udp::endpoint& to) {
    // A loopback UDP send does not block; a failed one is a lost packet, as on the real link.
    boost::system::error_code ec;
    socket.send_to(asio::buffer(bytes), to, 0, ec);
    if (!ec) ++stats.telemetry_sent;
  }

  struct HeldControl {
    Velocity velocity;
    udp::endpoint from;
  };
  struct HeldTelemetry {
    std::array<std::uint8_t, kTelemetryPacketSize> bytes;
    udp::endpoint to;
  };

  const SimOptions options;
  const VelocityConverter converter;  // only its const members: conversion back to SI and the minimums
  asio::io_context io;
  udp::socket socket;
  const std::uint16_t port;  // read once here: the socket belongs to the io thread once it runs
  asio::steady_timer physics_timer;
  asio::steady_timer telemetry_timer;
  std::thread thread;
  // Large enough for any datagram the robot might receive, so oversized ones arrive whole and are rejected.
  std::array<std::uint8_t, 65536> rx_buffer{};
  udp::endpoint rx_from;

  // Guarded by mutex: the io thread writes, the accessors read.
  mutable std::mutex mutex;
  std::mt19937_64 rng;
  double loss_probability;
  double reorder_probability;
  SimTruth truth;
  SimStats stats;
  std::uint64_t ticks = 0;
  bool fault = false;        // set_fault: reported by every motor record
  std::uint16_t faults = 0;  // how many times a fault was raised
  Clock::time_point last_step;
  std::optional<Clock::time_point> last_control;
  std::optional<udp::endpoint> operator_endpoint;
  std::optional<HeldControl> held_control;
  std::optional<HeldTelemetry> held_telemetry;
};

ServosilaSim::ServosilaSim(const SimOptions& options) {
  validate(options);
  impl_ = std::make_unique<Impl>(options);
  impl_->start();
}

ServosilaSim::~ServosilaSim() { impl_->stop(); }

std::uint16_t ServosilaSim::port() const { return impl_->port; }

SimTruth ServosilaSim::truth() const {
  const std::lock_guard lock(impl_->mutex);
  return impl_->truth;
}

SimStats ServosilaSim::stats() const {
  const std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

void ServosilaSim::set_loss_probability(double p) {
  require(probability(p), "loss probability must be in [0, 1]");
  const std::lock_guard lock(impl_->mutex);
  impl_->loss_probability = p;
}

void ServosilaSim::set_fault(bool fault) {
  const std::lock_guard lock(impl_->mutex);
  if (fault && !impl_->fault) ++impl_->faults;
  impl_->fault = fault;
}

void ServosilaSim::set_reorder_probability(double p) {
  require(probability(p), "reorder probability must be in [0, 1]");
  const std::lock_guard lock(impl_->mutex);
  impl_->reorder_probability = p;
}

}  // namespace wm::robot
