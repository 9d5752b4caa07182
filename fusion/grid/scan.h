#pragma once

#include <vector>

#include "fusion/geometry/pose2d.h"

namespace wm::fusion {

/// A laser scan like ROS sensor_msgs/LaserScan plus the sensor pose in the world. Beam i points at
/// sensor_pose.theta_rad + angle_min_rad + i·angle_increment_rad (world frame) from the sensor position.
/// Per beam: NaN, negative readings and readings below range_min_m are ignored (that beam only); a reading
/// >= range_max_m (including +inf) means "no return": free space up to range_max_m, no hit.
struct LaserScan {
  Pose2D sensor_pose;
  double angle_min_rad = 0;
  double angle_increment_rad = 0;
  std::vector<double> ranges_m;  // [m]
  double range_min_m = 0;        // [m]
  double range_max_m = 0;        // [m]
  double sigma_range_m = 0.01;   // standard deviation of a reading [m]
  /// The reading's σ grows by this per metre of range [m/m], >= 0: far walls marked with their real spread.
  double sigma_range_per_m = 0.0;
  /// Returns up to this range mark cells [m]; 0: the grid's SensorModelOptions::max_usable_range_m. A sensor that
  /// is good at 40 m says so here instead of having every return beyond the grid's default only clear space.
  double usable_range_m = 0.0;
};

/// A sonar ring: one transducer per entry of angles_rad (sensor frame, counter-clockwise from the sensor's x),
/// each a cone of beam_width_rad with its apex at the sensor position. Per-beam rules as LaserScan.
struct SonarScan {
  Pose2D sensor_pose;
  std::vector<double> angles_rad;  // [rad]
  std::vector<double> ranges_m;    // [m], one per angle
  double beam_width_rad = 0.4363;  // full aperture of each cone, 25° [rad]
  double range_min_m = 0;          // [m]
  double range_max_m = 0;          // [m]
  double sigma_range_m = 0.02;     // [m], plus 1 % of the reading (SensorModelOptions::sonar_sigma_per_range)
};

/// Largest supported beam aperture [rad]: the cone walk needs both cone edges within 90° of the walk axis.
inline constexpr double kMaxBeamWidthRad = 1.5707963267948966;  // π/2, exclusive

/// Largest range σ a scan may declare [m].
inline constexpr double kMaxSigmaRangeM = 10.0;

/// Checks a scan's own consistency. Individual readings are not checked (bad ones are skipped per beam).
/// @throw std::invalid_argument when the pose, angle_min or angle_increment is not finite, range_min_m is
///        negative or not finite, range_max_m is not finite or <= range_min_m, or sigma_range_m is not in
///        [0, kMaxSigmaRangeM]; for a laser scan also when sigma_range_per_m is not in [0, 1] or usable_range_m is
///        negative or not finite.
void validate(const LaserScan& scan);
/// @throw std::invalid_argument as for LaserScan, and when angles_rad and ranges_m differ in size, an angle is
///        not finite, or beam_width_rad is not in [0, π/2).
void validate(const SonarScan& scan);

}  // namespace wm::fusion
