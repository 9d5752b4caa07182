#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "fusion/geometry/line.h"
#include "fusion/geometry/pose2d.h"

namespace wm::fusion {

/// Edge of a rigid object, endpoints in the object's frame [m].
struct LocalEdge {
  Eigen::Vector2d p0;
  Eigen::Vector2d p1;
};

/// A not-deformable object: pose in the world with covariance, and its edges in its own frame.
/// Invariant: edges never change; only the pose does, so every world edge is regenerated from the pose
/// (lengths and angles between edges are kept exactly). pose_cov is symmetric positive semi-definite.
/// State s = (x [m], y [m], θ [rad]); edge k is the local line (ρ_kᵒ, φ_kᵒ) through its endpoints, observed as
/// h_k(s) = [ρ_kᵒ + x cos φ_k + y sin φ_k; φ_k], φ_k = φ_kᵒ + θ (docs/fusion.md §4, "Rigid object").
class RigidObject {
 public:
  /// @throw std::invalid_argument: no edges, degenerate edge (<1e-9 m), non-finite values, pose_cov not symmetric
  ///        (1e-9 relative to its largest entry) positive semi-definite.
  RigidObject(Pose2D pose, Eigen::Matrix3d pose_cov, std::vector<LocalEdge> edges);

  const Pose2D& pose() const { return pose_; }
  /// Over (x [m], y [m], θ [rad]).
  const Eigen::Matrix3d& pose_cov() const { return pose_cov_; }
  const std::vector<LocalEdge>& edges() const { return edges_; }

  /// Edge k in the world frame: endpoints by transforming the local endpoints with pose(); the line covariance
  /// is H P Hᵀ + edge_noise (H = ∂h_k/∂s, docs/fusion.md §4), so the gate sees the pose uncertainty. edge_noise
  /// [m², rad²] is added in the normalized world representation.
  /// @throw std::out_of_range for k >= edges().size(); std::invalid_argument for non-finite edge_noise.
  LineSegment world_edge(std::size_t k, const Eigen::Matrix2d& edge_noise) const;
  /// world_edge for every k, in edge order. @throw std::invalid_argument for non-finite edge_noise.
  std::vector<LineSegment> world_edges(const Eigen::Matrix2d& edge_noise) const;

  /// EKF update of the pose from one observed world line matched to edge k: z = observed (ρ,φ) with covariance
  /// R = observed.cov + edge_noise, re-expressed in h_k's representation (the closer of its two) before
  /// ν = z − h_k(s) is formed, ν's angle wrapped; S = HPHᵀ + R, K = PHᵀS⁻¹, s' = s + Kν (θ wrapped),
  /// P' = (I−KH)P(I−KH)ᵀ + KRKᵀ (Joseph form keeps P' symmetric PSD). Gating is the caller's job (best_match).
  /// Returns the updated object; *this is unchanged.
  /// @throw std::out_of_range for a bad k; std::invalid_argument if S is singular or input non-finite.
  RigidObject updated(std::size_t k, const LineFeature& observed, const Eigen::Matrix2d& edge_noise) const;

 private:
  Pose2D pose_;
  Eigen::Matrix3d pose_cov_;
  std::vector<LocalEdge> edges_;
};

}  // namespace wm::fusion
