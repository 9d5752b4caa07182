#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "clients/robot/odometry.h"
#include "clients/robot/servosila_units.h"

namespace wm::robot {

/// A simulated Servosila Engineer for tests and demos, a UDP peer that speaks the real protocol.
struct SimOptions {
  std::string bind_address = "127.0.0.1";  // numeric IPv4 or IPv6 address
  std::uint16_t port = 0;                  // 0: an ephemeral port (see ServosilaSim::port())
  /// Telemetry period [s] (> 0). The real robot sends telemetry once a second; tests use less.
  double telemetry_period_s = 1.0;
  /// Motion integration step [s] (> 0).
  double physics_period_s = 0.01;
  /// With no valid control packet for this long [s] (> 0), the robot stops. The operator sends five a second
  /// (0.2 s), so the default tolerates one lost packet and stops on the second.
  double watchdog_s = 0.5;
  /// Each datagram, in either direction, is lost with this probability ([0, 1]).
  double loss_probability = 0.0;
  /// Each datagram that is not lost is, with this probability ([0, 1]), held back and delivered just after the
  /// next one in the same direction (one held at a time): an older command can overtake a newer one.
  double reorder_probability = 0.0;
  std::uint64_t random_seed = 1;
  /// The axes ↔ SI conversion the operator uses, inverted here. Below the minimum magnitudes
  /// (VelocityConverter::min_drive_units(), min_turn_units()) the robot does not move, as the paper reports.
  VelocityConverterOptions units;
  /// The tracks as telemetry reports them: left_track_id, right_track_id, position_units_per_m, left_sign,
  /// right_sign, track_width_m and position_bits are used; the noise and filtering fields are ignored.
  OdometryOptions tracks;
  /// Both tracks' counts at start; near 2^position_bits it makes the counters wrap during a test.
  std::uint32_t initial_position = 0;
};

/// The simulator's ground truth.
struct SimTruth {
  double x_m = 0.0;
  double y_m = 0.0;
  double theta_rad = 0.0;     // in (−π, π]
  Velocity velocity;          // what the robot does now, after the stall and the watchdog
  double left_track_m = 0.0;  // distance each track has run, signed [m]
  double right_track_m = 0.0;
  bool watchdog_stopped = false;  // the last stop came from the watchdog (until the next valid packet)
};

/// Counters since start.
struct SimStats {
  std::uint64_t control_received = 0;   // valid control packets applied
  std::uint64_t control_lost = 0;       // dropped by the loss probability
  std::uint64_t control_reordered = 0;  // held back once
  std::uint64_t control_rejected = 0;   // not a valid control packet (size, frame type, non-finite)
  std::uint64_t telemetry_sent = 0;
  std::uint64_t telemetry_lost = 0;
  std::uint64_t telemetry_reordered = 0;
  std::uint64_t watchdog_stops = 0;
};

/// Listens for control packets on UDP and drives a unicycle model (x forward, y left, θ counter-clockwise)
/// with the commanded axes: v and ω by the inverse of the operator's conversion, zero below the minimum
/// speeds, zero when the watchdog trips. The tracks run at v ∓ ω·width/2; their counts go into a telemetry
/// packet (frame type 2, one record per track) sent every telemetry period to the address the last valid
/// control packet came from (nothing before the first). The tick is the number of physics steps since start.
/// All networking and integration run on one internal thread; the accessors are thread-safe.
class ServosilaSim {
 public:
  /// Binds the socket and starts the thread.
  /// @throw std::invalid_argument for invalid options (those of VelocityConverter included);
  ///        boost::system::system_error when the address is not numeric or the port cannot be bound.
  explicit ServosilaSim(const SimOptions& options = {});
  /// Stops the thread; the robot simply ceases to exist.
  ~ServosilaSim();
  ServosilaSim(const ServosilaSim&) = delete;
  ServosilaSim& operator=(const ServosilaSim&) = delete;

  /// The bound UDP port.
  std::uint16_t port() const;
  SimTruth truth() const;
  SimStats stats() const;
  /// Switch loss and reordering while running. @throw std::invalid_argument outside [0, 1].
  void set_loss_probability(double p);
  void set_reorder_probability(double p);
  /// Raises (true) or clears a motor fault: every motor record then reports fault_detected 1, and the faults
  /// counter counts each raise. The robot still moves (a real controller might not); this is for telemetry.
  void set_fault(bool fault);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wm::robot
