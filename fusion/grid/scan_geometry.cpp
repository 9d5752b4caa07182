#include "fusion/grid/scan_geometry.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wm::fusion {
namespace {

Eigen::Vector2d beam_point(const Pose2D& pose, double bearing_rad, double range_m) {
  return pose.transform_point({range_m * std::cos(bearing_rad), range_m * std::sin(bearing_rad)});
}

template <typename Scan>
Eigen::AlignedBox2d footprint(const Scan& scan, double reach_m, double beam_half_width_rad, double pad_m) {
  if (!std::isfinite(reach_m) || reach_m < 0 || !std::isfinite(pad_m) || pad_m < 0)
    throw std::invalid_argument("scan_footprint: reach_m and pad_m must be finite and >= 0");
  const auto& pose = scan.sensor_pose;
  Eigen::AlignedBox2d box(Eigen::Vector2d(pose.x_m, pose.y_m));
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double r = scan.ranges_m[i];
    if (!std::isfinite(r) || r <= 0) continue;
    box.extend(beam_point(pose, beam_bearing_rad(scan, i), std::min(r, reach_m)));
  }
  const double spread = reach_m * std::sin(std::min(beam_half_width_rad, 1.5));
  const Eigen::Vector2d grow = Eigen::Vector2d::Constant(pad_m + spread);
  return {box.min() - grow, box.max() + grow};
}

template <typename Scan>
std::vector<Eigen::Vector2d> returns(const Scan& scan, std::size_t max_points) {
  if (max_points == 0) throw std::invalid_argument("scan_returns: max_points must be > 0");
  std::vector<Eigen::Vector2d> points;
  const std::size_t step = std::max<std::size_t>(1, scan.ranges_m.size() / max_points);
  for (std::size_t i = 0; i < scan.ranges_m.size(); i += step) {
    const double r = scan.ranges_m[i];
    if (!std::isfinite(r) || r <= 0 || r >= scan.range_max_m) continue;
    points.push_back(beam_point(scan.sensor_pose, beam_bearing_rad(scan, i), r));
  }
  return points;
}

}  // namespace

double beam_bearing_rad(const LaserScan& scan, std::size_t i) {
  if (i >= scan.ranges_m.size()) throw std::out_of_range("beam_bearing_rad: beam index out of range");
  return scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
}

double beam_bearing_rad(const SonarScan& scan, std::size_t i) {
  if (i >= scan.angles_rad.size()) throw std::out_of_range("beam_bearing_rad: beam index out of range");
  return scan.angles_rad[i];
}

Eigen::AlignedBox2d scan_footprint(const LaserScan& scan, double reach_m, double beam_half_width_rad, double pad_m) {
  return footprint(scan, reach_m, beam_half_width_rad, pad_m);
}

Eigen::AlignedBox2d scan_footprint(const SonarScan& scan, double reach_m, double beam_half_width_rad, double pad_m) {
  return footprint(scan, reach_m, beam_half_width_rad, pad_m);
}

std::vector<Eigen::Vector2d> scan_returns(const LaserScan& scan, std::size_t max_points) {
  return returns(scan, max_points);
}

std::vector<Eigen::Vector2d> scan_returns(const SonarScan& scan, std::size_t max_points) {
  return returns(scan, max_points);
}

}  // namespace wm::fusion
