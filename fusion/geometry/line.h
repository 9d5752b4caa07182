#pragma once

#include <Eigen/Core>

#include "fusion/geometry/pose2d.h"

namespace wm::fusion {

/// An infinite line in Hesse normal form x·cosφ + y·sinφ = ρ with covariance over (ρ [m], φ [rad]).
/// (ρ, φ) and (−ρ, φ+π) are the same line; switching between them negates cov(ρ, φ) (Jacobian diag(−1, 1)).
/// Invariant after normalized(): rho_m >= 0, phi_rad in (−π, π], cov symmetric.
struct LineFeature {
  double rho_m = 0.0;
  double phi_rad = 0.0;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();  // over (rho [m], phi [rad])

  /// The same line with rho >= 0 and phi in (−π, π]; when rho was negated, cov(0,1) and cov(1,0) change sign.
  /// cov is symmetrised. A line through the origin keeps its φ (both normals are valid there).
  LineFeature normalized() const;
  /// Unit normal (cos φ, sin φ).
  Eigen::Vector2d normal() const;
  /// Unit direction (−sin φ, cos φ): the normal turned by +90°.
  Eigen::Vector2d direction() const;
  /// Signed distance of p from the line [m] (positive on the normal's side): p·n − ρ.
  double signed_distance(const Eigen::Vector2d& p) const;
  /// Coordinate of p's projection along direction() [m]: t = −p.x·sinφ + p.y·cosφ.
  double coordinate_along(const Eigen::Vector2d& p) const;
};

/// A line plus its extent [t0, t1] along line.direction(); endpoint(t) = ρ·n + t·d.
/// Invariant: t0_m <= t1_m, line normalized.
struct LineSegment {
  LineFeature line;
  double t0_m = 0.0;
  double t1_m = 0.0;

  /// Endpoint at t0 [m].
  Eigen::Vector2d p0() const;
  /// Endpoint at t1 [m].
  Eigen::Vector2d p1() const;
  /// t1 − t0 [m].
  double length_m() const;

  /// Segment through two points [m] with the given (rho, phi) covariance, which is taken as the covariance of the
  /// normalized line. Orders t0 <= t1 (so p0()/p1() may be the inputs swapped).
  /// @throw std::invalid_argument if the points are closer than 1e-9 m, non-finite, or cov is not finite,
  ///        symmetric (1e-12 relative to its largest entry) and positive definite.
  static LineSegment from_points(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Matrix2d& cov);
};

/// Expresses a line given in a local frame (pose relative to world) in the world frame, propagating both the
/// line covariance and the pose covariance (3x3 over x [m], y [m], θ [rad]) to first order — docs/fusion.md §4
/// "Robot frame to world frame": φ_w = φ + θ, ρ_w = ρ + x cos φ_w + y sin φ_w, C_w = J_L C_L J_Lᵀ + J_pose P J_poseᵀ.
/// The result is normalized. `local` may be in either representation.
/// @throw std::invalid_argument for non-finite input.
LineFeature transform_line(const LineFeature& local, const Pose2D& pose, const Eigen::Matrix3d& pose_cov);

/// A segment given in a local frame, in the world frame: its line as transform_line places it, its extent from the
/// transformed ends. @throw std::invalid_argument for non-finite input.
LineSegment transform_segment(const LineSegment& local, const Pose2D& pose, const Eigen::Matrix3d& pose_cov);

}  // namespace wm::fusion
