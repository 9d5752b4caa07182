#include "fusion/geometry/line.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "fusion/geometry/angle.h"
#include "fusion/internal/line_algebra.h"

namespace wm::fusion {

LineFeature LineFeature::normalized() const {
  LineFeature result = rho_m < 0.0 ? internal::flipped(*this) : *this;
  result.rho_m += 0.0;  // turns −0.0 into +0.0
  result.phi_rad = normalize_angle(result.phi_rad);
  result.cov = (0.5 * (result.cov + result.cov.transpose())).eval();  // eval: the transpose aliases
  return result;
}

Eigen::Vector2d LineFeature::normal() const { return {std::cos(phi_rad), std::sin(phi_rad)}; }

Eigen::Vector2d LineFeature::direction() const { return {-std::sin(phi_rad), std::cos(phi_rad)}; }

double LineFeature::signed_distance(const Eigen::Vector2d& p) const { return p.dot(normal()) - rho_m; }

double LineFeature::coordinate_along(const Eigen::Vector2d& p) const { return p.dot(direction()); }

Eigen::Vector2d LineSegment::p0() const { return line.rho_m * line.normal() + t0_m * line.direction(); }

Eigen::Vector2d LineSegment::p1() const { return line.rho_m * line.normal() + t1_m * line.direction(); }

double LineSegment::length_m() const { return t1_m - t0_m; }

LineSegment LineSegment::from_points(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Matrix2d& cov) {
  constexpr const char* kCaller = "LineSegment::from_points";
  constexpr double kMinSeparation = 1e-9;  // [m]
  if (!a.allFinite() || !b.allFinite()) throw std::invalid_argument(std::string(kCaller) + ": point is not finite");
  const Eigen::Vector2d ab = b - a;
  if (!(ab.norm() >= kMinSeparation))
    throw std::invalid_argument(std::string(kCaller) + ": points are closer than 1e-9 m");
  internal::require_symmetric_positive_definite(cov, 1e-12, kCaller, "cov");

  const Eigen::Vector2d d = ab / ab.norm();
  const Eigen::Vector2d n(d.y(), -d.x());  // d = (−sin φ, cos φ) ⇒ n = (d.y, −d.x)
  const LineFeature raw{n.dot(a), std::atan2(n.y(), n.x()), cov};
  LineSegment segment;
  segment.line = raw.normalized();
  segment.line.cov = 0.5 * (cov + cov.transpose());  // cov belongs to the normalized line, not to `raw`
  const double ta = segment.line.coordinate_along(a);
  const double tb = segment.line.coordinate_along(b);
  segment.t0_m = std::min(ta, tb);
  segment.t1_m = std::max(ta, tb);
  return segment;
}

LineFeature transform_line(const LineFeature& local, const Pose2D& pose, const Eigen::Matrix3d& pose_cov) {
  constexpr const char* kCaller = "transform_line";
  if (!std::isfinite(local.rho_m) || !std::isfinite(local.phi_rad))
    throw std::invalid_argument(std::string(kCaller) + ": line is not finite");
  internal::require_finite(local.cov, kCaller, "line cov");
  if (!std::isfinite(pose.x_m) || !std::isfinite(pose.y_m) || !std::isfinite(pose.theta_rad))
    throw std::invalid_argument(std::string(kCaller) + ": pose is not finite");
  internal::require_finite(pose_cov, kCaller, "pose_cov");

  const internal::TransformedLine w = internal::transform_line_raw(local.rho_m, local.phi_rad, pose);
  // Line and pose errors are independent, so their first-order contributions add (docs/fusion.md §4).
  const Eigen::Matrix2d cov = w.d_line * local.cov * w.d_line.transpose() + w.d_pose * pose_cov * w.d_pose.transpose();
  return LineFeature{w.rho_m, w.phi_rad, cov}.normalized();
}

LineSegment transform_segment(const LineSegment& local, const Pose2D& pose, const Eigen::Matrix3d& pose_cov) {
  LineSegment world;
  world.line = transform_line(local.line, pose, pose_cov);
  world.t0_m = world.line.coordinate_along(pose.transform_point(local.p0()));
  world.t1_m = world.line.coordinate_along(pose.transform_point(local.p1()));
  if (world.t0_m > world.t1_m) std::swap(world.t0_m, world.t1_m);
  return world;
}

}  // namespace wm::fusion
