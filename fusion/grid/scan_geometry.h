#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <vector>

#include "fusion/grid/scan.h"

namespace wm::fusion {

/// Direction of beam i in the sensor frame [rad], counter-clockwise from the sensor's x axis: angle_min_rad +
/// i·angle_increment_rad for a laser, angles_rad[i] for a sonar ring. The world direction adds
/// sensor_pose.theta_rad. @throw std::out_of_range when i is not a beam of the scan.
double beam_bearing_rad(const LaserScan& scan, std::size_t i);
double beam_bearing_rad(const SonarScan& scan, std::size_t i);

/// The world-frame box a scan can change in a grid [m]: the sensor position and every beam with a positive
/// finite reading, out to min(reading, reach_m), grown on every side by `pad_m` plus what a cone of
/// `beam_half_width_rad` spreads at reach_m (sin of the half width, capped at 1.5 rad). A beam's axis alone
/// misses the cells its cone reaches beside it; `pad_m` covers the cells the grid rounds to (e.g. two cells).
/// @throw std::invalid_argument when reach_m or pad_m is negative or not finite.
Eigen::AlignedBox2d scan_footprint(const LaserScan& scan, double reach_m, double beam_half_width_rad, double pad_m);
Eigen::AlignedBox2d scan_footprint(const SonarScan& scan, double reach_m, double beam_half_width_rad, double pad_m);

/// The world-frame points where beams returned (finite readings in (0, range_max_m)) [m], taking every k-th
/// beam with k = max(1, beams / max_points) so that about max_points points come back (at most 2·max_points).
/// @throw std::invalid_argument when max_points is 0.
std::vector<Eigen::Vector2d> scan_returns(const LaserScan& scan, std::size_t max_points);
std::vector<Eigen::Vector2d> scan_returns(const SonarScan& scan, std::size_t max_points);

}  // namespace wm::fusion
