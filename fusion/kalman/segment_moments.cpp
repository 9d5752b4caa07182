#include "fusion/kalman/segment_moments.h"

#include <algorithm>
#include <cmath>

namespace wm::fusion {

SegmentMoments SegmentMoments::of(const LineSegment& segment) {
  const Eigen::Vector2d a = segment.p0();
  const Eigen::Vector2d b = segment.p1();
  const Eigen::Vector2d centre = 0.5 * (a + b);
  const Eigen::Vector2d d = b - a;
  const double length = d.norm();
  SegmentMoments m;
  m.weight = length;
  m.first = length * centre;
  // A uniform distribution along d has covariance d·dᵀ/12 about its centre.
  m.second = length * (centre * centre.transpose() + d * d.transpose() / 12.0);
  return m;
}

SegmentMoments& SegmentMoments::operator+=(const SegmentMoments& other) {
  weight += other.weight;
  first += other.first;
  second += other.second;
  return *this;
}

double SegmentMoments::rms_offset_m() const {
  if (!(weight > 0.0)) return 0.0;
  const Eigen::Vector2d mean = first / weight;
  const Eigen::Matrix2d scatter = second / weight - mean * mean.transpose();
  // Smaller eigenvalue of a symmetric 2×2 matrix, in closed form.
  const double half_trace = 0.5 * (scatter(0, 0) + scatter(1, 1));
  const double half_diff = 0.5 * (scatter(0, 0) - scatter(1, 1));
  const double radius = std::hypot(half_diff, 0.5 * (scatter(0, 1) + scatter(1, 0)));
  return std::sqrt(std::max(0.0, half_trace - radius));
}

double SegmentMoments::rms_offset_from_m(const LineFeature& line) const {
  if (!(weight > 0.0)) return 0.0;
  // Mean of (n·p − ρ)² over the mass: nᵀ(second/w)n − 2ρ·n·(first/w) + ρ².
  const Eigen::Vector2d n = line.normal();
  const double mean_sq =
      n.dot(second * n) / weight - 2.0 * line.rho_m * n.dot(first) / weight + line.rho_m * line.rho_m;
  return std::sqrt(std::max(0.0, mean_sq));
}

std::optional<LineSegment> SegmentMoments::refit(const LineSegment& near) const {
  if (!(weight > 0.0)) return std::nullopt;
  const Eigen::Vector2d mean = first / weight;
  const Eigen::Matrix2d scatter = second / weight - mean * mean.transpose();
  const double sxy = 0.5 * (scatter(0, 1) + scatter(1, 0)), diff = scatter(0, 0) - scatter(1, 1);
  if (!(std::hypot(diff, 2.0 * sxy) > 0.0)) return std::nullopt;  // isotropic: every direction fits as well
  const double axis = 0.5 * std::atan2(2.0 * sxy, diff);
  Eigen::Vector2d normal(-std::sin(axis), std::cos(axis));
  if (normal.dot(near.line.normal()) < 0.0) normal = -normal;
  LineSegment fitted;
  fitted.line = LineFeature{normal.dot(mean), std::atan2(normal.y(), normal.x()), near.line.cov}.normalized();
  const double ta = fitted.line.coordinate_along(near.p0()), tb = fitted.line.coordinate_along(near.p1());
  fitted.t0_m = std::min(ta, tb);
  fitted.t1_m = std::max(ta, tb);
  return fitted;
}

std::array<double, 6> SegmentMoments::to_array() const {
  return {weight, first.x(), first.y(), second(0, 0), second(0, 1), second(1, 1)};
}

SegmentMoments SegmentMoments::from_array(const std::array<double, 6>& v) {
  SegmentMoments m;
  m.weight = v[0];
  m.first = Eigen::Vector2d(v[1], v[2]);
  m.second << v[3], v[4], v[4], v[5];
  return m;
}

}  // namespace wm::fusion
