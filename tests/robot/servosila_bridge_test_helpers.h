#pragma once

// The bridge tests' loopback helpers: a sink that keeps poses in memory, the log lines, options for loopback, and a
// scripted fake robot.

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
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "clients/robot/servosila_protocol.h"
#include "clients/robot/servosila_sim.h"
#include "clients/robot/servosila_units.h"

namespace wm::robot::bridge_test_helpers {

namespace asio = boost::asio;
using udp = asio::ip::udp;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

/// Calls `done` every 5 ms until it holds or `timeout` passes; true when it held.
inline bool wait_until(const std::function<bool()>& done, Clock::duration timeout) {
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

inline BridgeOptions test_options(std::uint16_t robot_port, LogLines& log) {
  BridgeOptions o;
  o.robot_host = "127.0.0.1";
  o.robot_port = robot_port;
  o.watchdog_s = 0.5;
  o.report_period_s = 0.05;
  o.command_timeout_s = 0.0;  // these tests hold one command for seconds; the timeout has tests of its own
  o.log = log.sink();
  return o;
}

inline SimOptions sim_options() {
  SimOptions o;
  o.telemetry_period_s = 0.05;
  o.watchdog_s = 10.0;  // so that only a stop packet can stop it
  return o;
}

inline MotorRecord track(std::uint8_t id, std::uint32_t position) {
  MotorRecord m;
  m.device_id = id;
  m.position = position;
  return m;
}

inline bool moving(const ServosilaSim& sim) {
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

inline AxisCommand axes_of(const ControlPacket& packet) { return VelocityConverter().read_axes(packet); }
inline bool is_stop(const ControlPacket& packet) {
  const AxisCommand a = axes_of(packet);
  return a.drive == 0 && a.turn == 0;
}

/// Waits (up to 300 ms) until the last control packet the robot got is a stop (or is not).
inline bool robot_gets_stop(const FakeRobot& robot, bool stop) {
  return wait_until(
      [&] {
        const auto last = robot.last();
        return last && is_stop(last->packet) == stop;
      },
      milliseconds(300));
}

}  // namespace wm::robot::bridge_test_helpers
