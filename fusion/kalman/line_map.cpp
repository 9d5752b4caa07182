#include "fusion/kalman/line_map.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <iterator>
#include <numbers>
#include <stdexcept>
#include <string>

#include "fusion/internal/line_algebra.h"

namespace wm::fusion {
namespace {

// Inverse of a covariance that must be positive definite, via Cholesky.
Eigen::Matrix2d information(const Eigen::Matrix2d& cov, const char* what) {
  const Eigen::LLT<Eigen::Matrix2d> llt(0.5 * (cov + cov.transpose()));
  if (!cov.allFinite() || llt.info() != Eigen::Success)
    throw std::invalid_argument(std::string("fuse: ") + what + " covariance is not positive definite");
  return llt.solve(Eigen::Matrix2d::Identity());
}

}  // namespace

double mahalanobis_squared(const LineFeature& a, const LineFeature& b) {
  return internal::align_to(a, b, "mahalanobis_squared").mahalanobis_sq;
}

double extent_gap_m(const LineSegment& element, const LineSegment& observed) {
  const double ta = element.line.coordinate_along(observed.p0());
  const double tb = element.line.coordinate_along(observed.p1());
  const double lo = std::min(ta, tb);
  const double hi = std::max(ta, tb);
  return std::max({0.0, lo - element.t1_m, element.t0_m - hi});
}

double offset_variance_at(const LineFeature& line, double t_m) {
  return line.cov(0, 0) - 2.0 * t_m * line.cov(0, 1) + t_m * t_m * line.cov(1, 1);
}

SegmentGate segment_gate(const LineSegment& element, const LineSegment& observed, const MatchOptions& options) {
  internal::require_finite(element.line.cov, "segment_gate", "element covariance");
  internal::require_finite(observed.line.cov, "segment_gate", "observed covariance");
  SegmentGate g;
  const LineFeature& e = element.line;
  const LineFeature& o = observed.line;
  // Undirected lines: the direction difference folded into [0, π/2].
  const double dphi = std::remainder(o.phi_rad - e.phi_rad, std::numbers::pi);
  g.angle_rad = std::abs(dphi);
  const double length = std::max(observed.length_m(), 1e-9);
  const double length_floor = options.angle_floor_from_length ? std::atan(options.min_offset_m / length) : 0.0;
  g.angle_limit_rad = std::max(
      {options.min_angle_rad, length_floor, options.gate_sigmas * std::sqrt(std::max(0.0, e.cov(1, 1) + o.cov(1, 1)))});

  // The observed segment's ends, projected on the element's line: the offset between two lines is largest at the
  // ends of an interval, and a part of the observation beyond the element must lie on its extension too (a wall
  // that bends by a few degrees is not the same element).
  const double ta = e.coordinate_along(observed.p0());
  const double tb = e.coordinate_along(observed.p1());
  g.gap_m = std::max({0.0, std::min(ta, tb) - element.t1_m, element.t0_m - std::max(ta, tb)});
  const double ends[2] = {std::min(ta, tb), std::max(ta, tb)};
  g.cost = (g.angle_rad / g.angle_limit_rad) * (g.angle_rad / g.angle_limit_rad);
  bool offsets_pass = true;
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector2d on_element = e.rho_m * e.normal() + ends[k] * e.direction();
    g.offset_m[k] = std::abs(o.signed_distance(on_element));
    const double variance = offset_variance_at(e, ends[k]) + offset_variance_at(o, o.coordinate_along(on_element));
    g.offset_limit_m[k] = std::max(options.min_offset_m, options.gate_sigmas * std::sqrt(std::max(0.0, variance)));
    offsets_pass = offsets_pass && g.offset_m[k] <= g.offset_limit_m[k];
    g.cost += (g.offset_m[k] / g.offset_limit_m[k]) * (g.offset_m[k] / g.offset_limit_m[k]);
  }
  g.passes = g.angle_rad <= g.angle_limit_rad && offsets_pass && g.gap_m <= options.max_gap_m;
  return g;
}

std::optional<MatchResult> match_segment(const LineSegment& element, const LineSegment& observed,
                                         const MatchOptions& options) {
  const SegmentGate gate = segment_gate(element, observed, options);
  if (!gate.passes) return std::nullopt;
  return MatchResult{0, mahalanobis_squared(element.line, observed.line), gate.cost};
}

std::optional<MatchResult> best_match(std::span<const LineSegment> candidates, const LineSegment& observed,
                                      const MatchOptions& options) {
  std::optional<MatchResult> best;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    auto m = match_segment(candidates[i], observed, options);
    // Strictly smaller, so the lower index keeps a tie.
    if (m && (!best || m->cost < best->cost)) {
      m->index = i;
      best = m;
    }
  }
  return best;
}

LineSegment fuse(const LineSegment& element, const LineSegment& observed) {
  const Eigen::Matrix2d info_a = information(element.line.cov, "element");
  const Eigen::Matrix2d info_b = information(observed.line.cov, "observed");
  const LineFeature& a = element.line;
  const LineFeature b = internal::align_to(a, observed.line, "fuse").line;

  // A sum of two positive definite information matrices is positive definite, so Cholesky cannot fail here.
  const Eigen::Matrix2d p = Eigen::LLT<Eigen::Matrix2d>(info_a + info_b).solve(Eigen::Matrix2d::Identity());
  const Eigen::Vector2d l =
      p * (info_a * Eigen::Vector2d(a.rho_m, a.phi_rad) + info_b * Eigen::Vector2d(b.rho_m, b.phi_rad));
  LineSegment fused;
  fused.line = LineFeature{l.x(), l.y(), 0.5 * (p + p.transpose())}.normalized();
  // Projected after normalizing, so t is measured along the fused line's final direction.
  const double t[4] = {fused.line.coordinate_along(element.p0()), fused.line.coordinate_along(element.p1()),
                       fused.line.coordinate_along(observed.p0()), fused.line.coordinate_along(observed.p1())};
  fused.t0_m = *std::min_element(std::begin(t), std::end(t));
  fused.t1_m = *std::max_element(std::begin(t), std::end(t));
  return fused;
}

LineSegment fuse(const LineSegment& element, const LineSegment& observed, const FusionOptions& options) {
  return with_covariance_floor(fuse(element, observed), options);
}

LineSegment with_covariance_floor(LineSegment segment, const FusionOptions& floor) {
  // Midpoint form M = A C Aᵀ with A = [[1, −t_mid], [0, 1]] (the inverse of midpoint_line_cov's lever arm).
  const double t_mid = 0.5 * (segment.t0_m + segment.t1_m);
  Eigen::Matrix2d to_mid;
  to_mid << 1.0, -t_mid, 0.0, 1.0;
  Eigen::Matrix2d mid = to_mid * segment.line.cov * to_mid.transpose();
  mid(0, 0) += std::max(0.0, floor.min_offset_sigma_m * floor.min_offset_sigma_m - mid(0, 0));
  mid(1, 1) += std::max(0.0, floor.min_angle_sigma_rad * floor.min_angle_sigma_rad - mid(1, 1));
  Eigen::Matrix2d from_mid;
  from_mid << 1.0, t_mid, 0.0, 1.0;
  const Eigen::Matrix2d cov = from_mid * mid * from_mid.transpose();
  segment.line.cov = 0.5 * (cov + cov.transpose());
  return segment;
}

}  // namespace wm::fusion
