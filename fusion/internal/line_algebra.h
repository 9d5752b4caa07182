#pragma once

#include <Eigen/Core>
#include <string_view>

#include "fusion/geometry/line.h"
#include "fusion/geometry/pose2d.h"

// Helpers shared by the fusion sources; not part of the public API (tests may use them).
namespace wm::fusion::internal {

/// Throws std::invalid_argument("<caller>: <what> ...") unless every entry is finite.
void require_finite(const Eigen::Ref<const Eigen::MatrixXd>& m, std::string_view caller, std::string_view what);
/// Throws std::invalid_argument unless m is symmetric within `rel_tol` of its largest entry and positive definite.
void require_symmetric_positive_definite(const Eigen::Matrix2d& m, double rel_tol, std::string_view caller,
                                         std::string_view what);

/// The other representation of the same line: (−ρ, φ+π) with φ wrapped and cov(ρ, φ) negated. Not normalized.
LineFeature flipped(const LineFeature& line);

/// `other` re-expressed in `reference`'s representation: of `other` and flipped(`other`) the one closer to
/// `reference` in Mahalanobis distance under reference.cov + other.cov, with φ unwrapped to within π of
/// reference.phi_rad, so (line.rho − ref.rho, line.phi − ref.phi) is the innovation directly.
struct AlignedLine {
  LineFeature line;
  double mahalanobis_sq = 0.0;
};
/// @throw std::invalid_argument if reference.cov + other.cov is not positive definite.
AlignedLine align_to(const LineFeature& reference, const LineFeature& other, std::string_view caller);

/// A local line mapped into the world by a pose, in the representation the formula gives (not normalized),
/// with the Jacobians of docs/fusion.md §4: d_line = ∂(ρ_w, φ_w)/∂(ρ, φ), d_pose = ∂(ρ_w, φ_w)/∂(x, y, θ).
/// d_pose is the measurement Jacobian H of a rigid object's edge.
struct TransformedLine {
  double rho_m = 0.0;
  double phi_rad = 0.0;
  Eigen::Matrix2d d_line;
  Eigen::Matrix<double, 2, 3> d_pose;
};
TransformedLine transform_line_raw(double rho_m, double phi_rad, const Pose2D& pose);

}  // namespace wm::fusion::internal
