#pragma once

#include <Eigen/Core>
#include <span>

#include "fusion/geometry/line.h"

namespace wm::fusion {

/// Fits a line to points [m], each with a 2x2 covariance [m²], by weighted total least squares (docs/fusion.md §2):
/// weighted centroid and central moments S_xx, S_yy, S_xy, then α = ½·atan2(−2S_xy, S_yy − S_xx),
/// r = x̄ cos α + ȳ sin α. The weights are w_i = 1/σ_i² with σ_i² = nᵀQ_i n the point variance along the fitted
/// normal: a first pass uses trace(Q_i)/2, then the weights are recomputed from the fitted normal twice.
/// The covariance is C_L = Σ J_i Q_i J_iᵀ with the analytic Jacobians J_i = ∂(r, α)/∂(x_i, y_i) of docs/fusion.md §2
/// (Arras & Siegwart 1997), weights held fixed (their dependence on α only enters at second order).
/// The result is normalized (ρ >= 0, φ in (−π, π]).
/// @throw std::invalid_argument for fewer than 2 points, sizes that differ, non-finite input, covariances that are
///        not symmetric positive definite, all points coincident (within 1e-9 m) or points without a dominant
///        direction (isotropic spread).
LineFeature fit_line(std::span<const Eigen::Vector2d> points, std::span<const Eigen::Matrix2d> point_covs);

/// Same, with an isotropic standard deviation per point [m] (Q_i = σ_i²·I).
/// @throw std::invalid_argument as above, and for a sigma that is not finite and > 0.
LineFeature fit_line(std::span<const Eigen::Vector2d> points, std::span<const double> sigmas_m);

}  // namespace wm::fusion
