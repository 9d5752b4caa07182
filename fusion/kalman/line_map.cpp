#include "fusion/kalman/line_map.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <iterator>
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

std::optional<double> match_distance(const LineSegment& element, const LineSegment& observed,
                                     const MatchOptions& options) {
  const double d2 = mahalanobis_squared(element.line, observed.line);
  if (!(d2 <= options.gate_chi2)) return std::nullopt;
  if (!(extent_gap_m(element, observed) <= options.max_gap_m)) return std::nullopt;
  return d2;
}

std::optional<MatchResult> best_match(std::span<const LineSegment> candidates, const LineSegment& observed,
                                      const MatchOptions& options) {
  std::optional<MatchResult> best;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const auto d2 = match_distance(candidates[i], observed, options);
    // Strictly smaller, so the lower index keeps a tie.
    if (d2 && (!best || *d2 < best->mahalanobis_sq)) best = MatchResult{i, *d2};
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

}  // namespace wm::fusion
