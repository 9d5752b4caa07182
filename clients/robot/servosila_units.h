#pragma once

#include <cstddef>
#include <cstdint>

#include "clients/robot/servosila_protocol.h"

namespace wm::robot {

/// Drive-axis units per m/s of forward speed: the mean of nine runs from 6 000 to 30 000 units (0.083–0.414 m/s),
/// each timing 40 turns of the 1.15 m track with the robot on blocks (tracks in the air, so no slip).
/// The runs scatter from 71 609 to 72 391; the stated uncertainty is about 3 %.
inline constexpr double kDriveUnitsPerMps = 72021.73913;
/// Turn-axis units per rad/s: 24 000 in four of five runs from 10 000 to 30 000 units (one gave 23 913; the
/// authors state 24 000, not the mean 23 982.6). Measured on blocks as track speed divided by an assumed 0.1 m
/// turning radius, not as a rotation on the floor, so a real turn on the spot will differ (track slip).
inline constexpr double kTurnUnitsPerRadps = 24000.0;
/// The robot does not move below these speeds (the motors' current limits); the authors' controller sends
/// exactly this speed, with the command's sign, for any non-zero command below it.
inline constexpr double kMinimumLinearMps = 0.2;
inline constexpr double kMinimumAngularRadps = 0.2;

/// How SI velocities become the control packet's axes. The defaults are the measured constants and the axes the
/// authors' library drives; the signs and limits must be checked on a real robot (PROTOCOL.md).
struct VelocityConverterOptions {
  double drive_units_per_mps = kDriveUnitsPerMps;    // > 0
  double turn_units_per_radps = kTurnUnitsPerRadps;  // > 0
  /// Commands are clamped to ± these [m/s], [rad/s]. The defaults are the fastest calibrated runs (30 000 units:
  /// 0.4165 m/s by the constant, 1.25 rad/s); beyond them the constants are extrapolated.
  double max_linear_mps = 0.4;
  double max_angular_radps = 1.25;
  /// A non-zero command smaller than these is raised to them (sign kept) [m/s], [rad/s]; 0 disables. ≤ the max.
  double min_linear_mps = kMinimumLinearMps;
  double min_angular_radps = kMinimumAngularRadps;
  /// Axis indices (0..15, distinct): the authors' library drives the platform with axis 1 (forward/backward)
  /// and axis 0 (rotation), as the game controller's left stick does.
  std::size_t drive_axis = 1;
  std::size_t turn_axis = 0;
  /// +1 or −1. Forward is negative on axis 1 (the authors' library negates forward speeds). The turn sign is an
  /// assumption: a joystick's X axis is positive to the right, so a positive axis 0 turns clockwise, i.e.
  /// −ω in the right-handed frame used here (x forward, y left, θ counter-clockwise).
  int drive_sign = -1;
  int turn_sign = -1;
};

/// Raw platform axes of a control packet.
struct AxisCommand {
  std::int16_t drive = 0;
  std::int16_t turn = 0;
  bool operator==(const AxisCommand&) const = default;
};

/// A body velocity: forward [m/s] and counter-clockwise turn rate [rad/s].
struct Velocity {
  double linear_mps = 0.0;
  double angular_radps = 0.0;
};

/// What convert() sent and what it changed on the way.
struct ConversionResult {
  AxisCommand axes;
  Velocity sent;           // the velocity the axes stand for, after clamping, the minimum and rounding
  bool rejected = false;   // an input was NaN or ±∞: both axes are zero (a stop)
  bool clamped = false;    // a component was beyond its limit
  bool raised = false;     // a non-zero component below its minimum was raised to it
  bool saturated = false;  // a component fell outside int16 (only with limits configured past 0.455 m/s, 1.36 rad/s)
};

/// Converts SI velocity commands to axis units and back. Keeps counters, so one instance per command stream;
/// not thread-safe.
class VelocityConverter {
 public:
  /// @throw std::invalid_argument for a non-positive or non-finite constant, a negative or non-finite limit, a
  ///        minimum above its maximum, an axis index ≥ 16, equal axes, or a sign other than ±1.
  explicit VelocityConverter(const VelocityConverterOptions& options = {});

  /// Clamps each component to its limit, raises a non-zero one below its minimum to the minimum (sign kept),
  /// rounds to the nearest axis unit and saturates to int16. NaN or ±∞ in either component gives a stop
  /// (both axes 0) and counts as rejected: a controller must never guess a speed.
  ConversionResult convert(double linear_mps, double angular_radps);

  /// The velocity the axes command, by the constants alone (no minimum applied: the robot's stall is the
  /// caller's model, see min_drive_units()).
  Velocity to_velocity(const AxisCommand& axes) const;

  /// The smallest axis magnitudes convert() sends for a non-zero command: the configured minimums in axis units,
  /// rounded. A simulated robot stalls below them.
  std::int16_t min_drive_units() const { return min_drive_units_; }
  std::int16_t min_turn_units() const { return min_turn_units_; }

  /// Writes the axes into their slots of the packet; other axes and buttons are untouched.
  void write_axes(const AxisCommand& axes, ControlPacket& packet) const;
  AxisCommand read_axes(const ControlPacket& packet) const;

  std::uint64_t rejected_count() const { return rejected_count_; }
  std::uint64_t clamped_count() const { return clamped_count_; }
  std::uint64_t raised_count() const { return raised_count_; }
  const VelocityConverterOptions& options() const { return options_; }

 private:
  const VelocityConverterOptions options_;
  std::int16_t min_drive_units_ = 0;
  std::int16_t min_turn_units_ = 0;
  std::uint64_t rejected_count_ = 0;
  std::uint64_t clamped_count_ = 0;
  std::uint64_t raised_count_ = 0;
};

}  // namespace wm::robot
