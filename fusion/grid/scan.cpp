#include "fusion/grid/scan.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace wm::fusion {
namespace {

void check_common(const char* fn, const Pose2D& pose, double range_min_m, double range_max_m, double sigma_m) {
  const auto fail = [fn](const std::string& what) { throw std::invalid_argument(std::string(fn) + ": " + what); };
  if (!std::isfinite(pose.x_m) || !std::isfinite(pose.y_m) || !std::isfinite(pose.theta_rad)) {
    fail("sensor_pose must be finite");
  }
  if (!std::isfinite(range_min_m) || range_min_m < 0.0) fail("range_min_m must be finite and >= 0");
  if (!std::isfinite(range_max_m) || !(range_max_m > range_min_m)) {
    fail("range_max_m must be finite and > range_min_m");
  }
  // A wider σ only makes the hit band a wall kilometres thick (and its walk as long); the HTTP API caps it alike.
  if (!(sigma_m >= 0.0 && sigma_m <= kMaxSigmaRangeM)) fail("sigma_range_m must be in [0, 10] m");
}

}  // namespace

void validate(const LaserScan& scan) {
  check_common("validate(LaserScan)", scan.sensor_pose, scan.range_min_m, scan.range_max_m, scan.sigma_range_m);
  if (!std::isfinite(scan.angle_min_rad) || !std::isfinite(scan.angle_increment_rad)) {
    throw std::invalid_argument("validate(LaserScan): angle_min_rad and angle_increment_rad must be finite");
  }
  if (!(scan.sigma_range_per_m >= 0 && scan.sigma_range_per_m <= 1))
    throw std::invalid_argument("validate(LaserScan): sigma_range_per_m must be in [0, 1] m/m");
  if (!(scan.usable_range_m >= 0 && std::isfinite(scan.usable_range_m)))
    throw std::invalid_argument("validate(LaserScan): usable_range_m must be >= 0 and finite (0: the grid's own)");
}

void validate(const SonarScan& scan) {
  check_common("validate(SonarScan)", scan.sensor_pose, scan.range_min_m, scan.range_max_m, scan.sigma_range_m);
  if (scan.angles_rad.size() != scan.ranges_m.size()) {
    throw std::invalid_argument("validate(SonarScan): angles_rad and ranges_m differ in size (" +
                                std::to_string(scan.angles_rad.size()) + " vs " + std::to_string(scan.ranges_m.size()) +
                                ")");
  }
  for (const double a : scan.angles_rad) {
    if (!std::isfinite(a)) throw std::invalid_argument("validate(SonarScan): angles_rad must be finite");
  }
  if (!(scan.beam_width_rad >= 0.0 && scan.beam_width_rad < kMaxBeamWidthRad)) {
    throw std::invalid_argument("validate(SonarScan): beam_width_rad must be in [0, pi/2)");
  }
}

}  // namespace wm::fusion
