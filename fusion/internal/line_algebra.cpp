#include "fusion/internal/line_algebra.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <initializer_list>
#include <numbers>
#include <stdexcept>
#include <string>

#include "fusion/geometry/angle.h"

namespace wm::fusion::internal {
namespace {

[[noreturn]] void fail(std::string_view caller, std::string_view message) {
  throw std::invalid_argument(std::string(caller) + ": " + std::string(message));
}

// d² = Δᵀ C⁻¹ Δ, or NaN when C is not positive definite.
double mahalanobis_sq_or_nan(const Eigen::Vector2d& delta, const Eigen::Matrix2d& cov) {
  const Eigen::LLT<Eigen::Matrix2d> llt(cov);
  if (llt.info() != Eigen::Success) return std::nan("");
  return delta.dot(llt.solve(delta));
}

LineFeature unwrapped_near(const LineFeature& line, double reference_phi_rad) {
  LineFeature result = line;
  result.phi_rad = reference_phi_rad + normalize_angle(line.phi_rad - reference_phi_rad);
  return result;
}

}  // namespace

void require_finite(const Eigen::Ref<const Eigen::MatrixXd>& m, std::string_view caller, std::string_view what) {
  if (!m.allFinite()) fail(caller, std::string(what) + " is not finite");
}

void require_symmetric_positive_definite(const Eigen::Matrix2d& m, double rel_tol, std::string_view caller,
                                         std::string_view what) {
  require_finite(m, caller, what);
  const double scale = m.cwiseAbs().maxCoeff();
  if (std::abs(m(0, 1) - m(1, 0)) > rel_tol * scale) fail(caller, std::string(what) + " is not symmetric");
  // LLT reports a non-positive pivot, which is exactly "not positive definite" for a symmetric 2x2.
  const Eigen::Matrix2d symmetric = 0.5 * (m + m.transpose());
  if (Eigen::LLT<Eigen::Matrix2d>(symmetric).info() != Eigen::Success)
    fail(caller, std::string(what) + " is not positive definite");
}

LineFeature flipped(const LineFeature& line) {
  const Eigen::Matrix2d f = Eigen::Vector2d(-1.0, 1.0).asDiagonal();
  return LineFeature{-line.rho_m, normalize_angle(line.phi_rad + std::numbers::pi), f * line.cov * f};
}

AlignedLine align_to(const LineFeature& reference, const LineFeature& other, std::string_view caller) {
  for (const LineFeature* line : {&reference, &other}) {
    if (!std::isfinite(line->rho_m) || !std::isfinite(line->phi_rad)) fail(caller, "line is not finite");
    require_finite(line->cov, caller, "line cov");
  }
  const LineFeature candidates[2] = {unwrapped_near(other, reference.phi_rad),
                                     unwrapped_near(flipped(other), reference.phi_rad)};
  AlignedLine best{candidates[0], 0.0};
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector2d delta(candidates[i].rho_m - reference.rho_m, candidates[i].phi_rad - reference.phi_rad);
    const double d2 = mahalanobis_sq_or_nan(delta, reference.cov + candidates[i].cov);
    if (std::isnan(d2)) fail(caller, "sum of the line covariances is not positive definite");
    if (i == 0 || d2 < best.mahalanobis_sq) best = AlignedLine{candidates[i], d2};
  }
  return best;
}

TransformedLine transform_line_raw(double rho_m, double phi_rad, const Pose2D& pose) {
  // docs/fusion.md §4: φ_w = φ + θ, ρ_w = ρ + x cos φ_w + y sin φ_w. The along-line coordinate of the pose origin,
  // −x sin φ_w + y cos φ_w, is the lever arm through which φ (and θ) errors move ρ_w.
  const double phi_w = normalize_angle(phi_rad + pose.theta_rad);
  const double c = std::cos(phi_w);
  const double s = std::sin(phi_w);
  const double lever = -pose.x_m * s + pose.y_m * c;
  TransformedLine out;
  out.rho_m = rho_m + pose.x_m * c + pose.y_m * s;
  out.phi_rad = phi_w;
  out.d_line << 1.0, lever, 0.0, 1.0;
  out.d_pose << c, s, lever, 0.0, 0.0, 1.0;
  return out;
}

}  // namespace wm::fusion::internal
