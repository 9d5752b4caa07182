#include "fusion/lines/line_fit.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "fusion/internal/line_algebra.h"

namespace wm::fusion {
namespace {

constexpr const char* kCaller = "fit_line";
constexpr int kReweightPasses = 2;
constexpr double kMinSpread = 1e-9;  // [m] rms distance from the centroid below which the points coincide

[[noreturn]] void fail(const std::string& message) {
  throw std::invalid_argument(std::string(kCaller) + ": " + message);
}

// Weighted TLS solution in the representation the closed form yields (α in (−π/2, π/2], r of either sign),
// with the moments the Jacobians need.
struct RawFit {
  Eigen::Vector2d centroid;
  double total_weight = 0.0;
  double n = 0.0;  // N = −2 S_xy
  double d = 0.0;  // D = S_yy − S_xx
  double alpha_rad = 0.0;
  double r_m = 0.0;
};

RawFit solve(std::span<const Eigen::Vector2d> points, const std::vector<double>& weights) {
  RawFit fit;
  fit.centroid.setZero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    fit.total_weight += weights[i];
    fit.centroid += weights[i] * points[i];
  }
  fit.centroid /= fit.total_weight;
  double sxx = 0.0, syy = 0.0, sxy = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d q = points[i] - fit.centroid;
    sxx += weights[i] * q.x() * q.x();
    syy += weights[i] * q.y() * q.y();
    sxy += weights[i] * q.x() * q.y();
  }
  const double spread = sxx + syy;
  if (!(spread > kMinSpread * kMinSpread * fit.total_weight)) fail("all points coincide");
  fit.n = -2.0 * sxy;
  fit.d = syy - sxx;
  // N = D = 0 means the scatter is isotropic: every direction fits equally well.
  if (std::hypot(fit.n, fit.d) <= 1e-12 * spread) fail("points have no dominant direction");
  fit.alpha_rad = 0.5 * std::atan2(fit.n, fit.d);
  fit.r_m = fit.centroid.x() * std::cos(fit.alpha_rad) + fit.centroid.y() * std::sin(fit.alpha_rad);
  return fit;
}

// C_L = Σ J_i Q_i J_iᵀ, docs/fusion.md §2:
//   ∂α/∂x_i = w_i[−D(y_i−ȳ) + N(x_i−x̄)]/Q,  ∂α/∂y_i = w_i[−D(x_i−x̄) − N(y_i−ȳ)]/Q,  Q = N² + D²,
//   ∂r/∂(x_i, y_i) = (w_i/W)(cos α, sin α) + t_c·∂α/∂(x_i, y_i),  t_c = −x̄ sin α + ȳ cos α.
Eigen::Matrix2d covariance(std::span<const Eigen::Vector2d> points, std::span<const Eigen::Matrix2d> covs,
                           const std::vector<double>& weights, const RawFit& fit) {
  const double q = fit.n * fit.n + fit.d * fit.d;
  const double c = std::cos(fit.alpha_rad);
  const double s = std::sin(fit.alpha_rad);
  const double t_c = -fit.centroid.x() * s + fit.centroid.y() * c;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d u = points[i] - fit.centroid;
    const double w = weights[i];
    const Eigen::RowVector2d d_alpha(w * (-fit.d * u.y() + fit.n * u.x()) / q,
                                     w * (-fit.d * u.x() - fit.n * u.y()) / q);
    Eigen::Matrix2d j;
    j.row(0) = (w / fit.total_weight) * Eigen::RowVector2d(c, s) + t_c * d_alpha;
    j.row(1) = d_alpha;
    cov += j * covs[i] * j.transpose();
  }
  return cov;
}

void validate(std::span<const Eigen::Vector2d> points, std::span<const Eigen::Matrix2d> covs) {
  if (points.size() < 2) fail("need at least 2 points, got " + std::to_string(points.size()));
  if (points.size() != covs.size())
    fail("got " + std::to_string(points.size()) + " points but " + std::to_string(covs.size()) + " covariances");
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) fail("point " + std::to_string(i) + " is not finite");
    internal::require_symmetric_positive_definite(covs[i], 1e-12, kCaller, "covariance " + std::to_string(i));
  }
}

}  // namespace

LineFeature fit_line(std::span<const Eigen::Vector2d> points, std::span<const Eigen::Matrix2d> point_covs) {
  validate(points, point_covs);
  // The first pass does not know the normal yet, so it uses the mean variance over all directions.
  std::vector<double> weights(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) weights[i] = 2.0 / point_covs[i].trace();
  RawFit fit = solve(points, weights);
  for (int pass = 0; pass < kReweightPasses; ++pass) {
    const Eigen::Vector2d normal(std::cos(fit.alpha_rad), std::sin(fit.alpha_rad));
    for (std::size_t i = 0; i < points.size(); ++i) weights[i] = 1.0 / normal.dot(point_covs[i] * normal);
    fit = solve(points, weights);
  }
  return LineFeature{fit.r_m, fit.alpha_rad, covariance(points, point_covs, weights, fit)}.normalized();
}

LineFeature fit_line(std::span<const Eigen::Vector2d> points, std::span<const double> sigmas_m) {
  std::vector<Eigen::Matrix2d> covs;
  covs.reserve(sigmas_m.size());
  for (std::size_t i = 0; i < sigmas_m.size(); ++i) {
    if (!std::isfinite(sigmas_m[i]) || !(sigmas_m[i] > 0.0))
      fail("sigma " + std::to_string(i) + " must be finite and > 0");
    covs.push_back(sigmas_m[i] * sigmas_m[i] * Eigen::Matrix2d::Identity());
  }
  return fit_line(points, std::span<const Eigen::Matrix2d>(covs));
}

}  // namespace wm::fusion
