#include "clients/robot/servosila_units.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace wm::robot {

namespace {

constexpr double kInt16Max = std::numeric_limits<std::int16_t>::max();
constexpr double kInt16Min = std::numeric_limits<std::int16_t>::min();

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument("VelocityConverter: " + message);
}

bool positive_finite(double v) { return std::isfinite(v) && v > 0.0; }
bool non_negative_finite(double v) { return std::isfinite(v) && v >= 0.0; }

/// One velocity component after the limit and the minimum.
struct Shaped {
  double value = 0.0;
  bool clamped = false;
  bool raised = false;
};

Shaped shape(double value, double max, double min) {
  Shaped s{value, false, false};
  if (std::abs(s.value) > max) {
    s.value = std::copysign(max, s.value);
    s.clamped = true;
  }
  if (s.value != 0.0 && std::abs(s.value) < min) {
    s.value = std::copysign(min, s.value);
    s.raised = true;
  }
  return s;
}

std::int16_t to_units(double value, double units_per_si, int sign, bool& saturated) {
  const double units = std::round(value * units_per_si * sign);
  if (units > kInt16Max) {
    saturated = true;
    return std::numeric_limits<std::int16_t>::max();
  }
  if (units < kInt16Min) {
    saturated = true;
    return std::numeric_limits<std::int16_t>::min();
  }
  return static_cast<std::int16_t>(units);
}

std::int16_t minimum_units(double min_si, double units_per_si) {
  return static_cast<std::int16_t>(std::min(std::round(min_si * units_per_si), kInt16Max));
}

}  // namespace

VelocityConverter::VelocityConverter(const VelocityConverterOptions& options) : options_(options) {
  require(positive_finite(options_.drive_units_per_mps), "drive_units_per_mps must be finite and > 0");
  require(positive_finite(options_.turn_units_per_radps), "turn_units_per_radps must be finite and > 0");
  require(non_negative_finite(options_.max_linear_mps), "max_linear_mps must be finite and >= 0");
  require(non_negative_finite(options_.max_angular_radps), "max_angular_radps must be finite and >= 0");
  require(non_negative_finite(options_.min_linear_mps) && options_.min_linear_mps <= options_.max_linear_mps,
          "min_linear_mps must be in [0, max_linear_mps]");
  require(non_negative_finite(options_.min_angular_radps) && options_.min_angular_radps <= options_.max_angular_radps,
          "min_angular_radps must be in [0, max_angular_radps]");
  require(options_.drive_axis < kAxisCount && options_.turn_axis < kAxisCount, "axis index must be < 16");
  require(options_.drive_axis != options_.turn_axis, "drive_axis and turn_axis must differ");
  require(options_.drive_sign == 1 || options_.drive_sign == -1, "drive_sign must be +1 or -1");
  require(options_.turn_sign == 1 || options_.turn_sign == -1, "turn_sign must be +1 or -1");
  // Only after validation: a NaN minimum must not reach the int16 conversion.
  min_drive_units_ = minimum_units(options_.min_linear_mps, options_.drive_units_per_mps);
  min_turn_units_ = minimum_units(options_.min_angular_radps, options_.turn_units_per_radps);
}

ConversionResult VelocityConverter::convert(double linear_mps, double angular_radps) {
  ConversionResult result;
  if (!std::isfinite(linear_mps) || !std::isfinite(angular_radps)) {
    result.rejected = true;
    ++rejected_count_;
    return result;
  }
  const Shaped linear = shape(linear_mps, options_.max_linear_mps, options_.min_linear_mps);
  const Shaped angular = shape(angular_radps, options_.max_angular_radps, options_.min_angular_radps);
  result.clamped = linear.clamped || angular.clamped;
  result.raised = linear.raised || angular.raised;
  result.axes.drive = to_units(linear.value, options_.drive_units_per_mps, options_.drive_sign, result.saturated);
  result.axes.turn = to_units(angular.value, options_.turn_units_per_radps, options_.turn_sign, result.saturated);
  result.sent = to_velocity(result.axes);
  if (result.clamped) ++clamped_count_;
  if (result.raised) ++raised_count_;
  return result;
}

Velocity VelocityConverter::to_velocity(const AxisCommand& axes) const {
  return Velocity{options_.drive_sign * axes.drive / options_.drive_units_per_mps,
                  options_.turn_sign * axes.turn / options_.turn_units_per_radps};
}

void VelocityConverter::write_axes(const AxisCommand& axes, ControlPacket& packet) const {
  packet.axes[options_.drive_axis] = axes.drive;
  packet.axes[options_.turn_axis] = axes.turn;
}

AxisCommand VelocityConverter::read_axes(const ControlPacket& packet) const {
  return AxisCommand{packet.axes[options_.drive_axis], packet.axes[options_.turn_axis]};
}

}  // namespace wm::robot
