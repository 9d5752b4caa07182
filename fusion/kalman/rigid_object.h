#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <optional>
#include <span>
#include <vector>

#include "fusion/geometry/line.h"
#include "fusion/geometry/pose2d.h"

namespace wm::fusion {

/// Edge of a rigid object, endpoints in the object's frame [m].
struct LocalEdge {
  Eigen::Vector2d p0;
  Eigen::Vector2d p1;
};

/// One observed world line matched to edge `edge` of a rigid object, for a joint update.
struct EdgeObservation {
  std::size_t edge = 0;
  LineFeature observed;  // world frame, either representation, with its (ρ [m], φ [rad]) covariance
  /// The drawing's own uncertainty of the edge [m², rad²], in the normalized world representation of the edge at
  /// the object's current pose (what world_edge(edge, 0) gives).
  Eigen::Matrix2d edge_noise = Eigen::Matrix2d::Zero();
};

/// How the iterated update runs.
struct RigidUpdateOptions {
  /// Where the iteration starts (e.g. a pose found by shape, see find_by_shape); nullopt: the current pose. The
  /// prior stays the current pose and covariance wherever the iteration starts.
  std::optional<Pose2D> start;
  /// Gauss–Newton steps at most; 1 is the plain EKF about the start.
  std::size_t max_iterations = 30;
  /// Converged when a step is below this ([m] and [rad] about the centroid).
  double tolerance = 1e-10;
};

/// A not-deformable object: pose in the world with covariance, and its edges in its own frame.
/// Invariant: edges never change; only the pose does, so every world edge is regenerated from the pose
/// (lengths and angles between edges are kept exactly). pose_cov is symmetric positive semi-definite.
/// State s = (x [m], y [m], θ [rad]) of the object frame's origin. Updates are solved about the edges' centroid,
/// in a frame at the object's current pose (docs/fusion.md §4, "Rigid object"), so the distance of the object
/// from the world origin does not turn into a lever arm.
class RigidObject {
 public:
  /// @throw std::invalid_argument: no edges, degenerate edge (<1e-9 m), non-finite values, pose_cov not symmetric
  ///        (1e-9 relative to its largest entry) positive semi-definite.
  RigidObject(Pose2D pose, Eigen::Matrix3d pose_cov, std::vector<LocalEdge> edges);

  const Pose2D& pose() const { return pose_; }
  /// Over (x [m], y [m], θ [rad]).
  const Eigen::Matrix3d& pose_cov() const { return pose_cov_; }
  const std::vector<LocalEdge>& edges() const { return edges_; }
  /// The length-weighted centroid of the edges in the object frame [m]: the point updates rotate about.
  Eigen::Vector2d local_centroid() const;

  /// Edge k in the world frame: endpoints by transforming the local endpoints with pose(); the line covariance
  /// is H P Hᵀ + edge_noise (H = ∂h_k/∂s, docs/fusion.md §4), so the gate sees the pose uncertainty. edge_noise
  /// [m², rad²] is added in the normalized world representation.
  /// @throw std::out_of_range for k >= edges().size(); std::invalid_argument for non-finite edge_noise.
  LineSegment world_edge(std::size_t k, const Eigen::Matrix2d& edge_noise) const;
  /// world_edge for every k, in edge order. @throw std::invalid_argument for non-finite edge_noise.
  std::vector<LineSegment> world_edges(const Eigen::Matrix2d& edge_noise) const;

  /// Iterated EKF update of the pose from several observed lines at once (one joint measurement; one edge alone
  /// fixes only θ and the translation along its normal). Each line is expressed in a frame at the centroid, turned
  /// by θ, where h_k = [ρ_kᶜ + u·n(φ_kᵒ + α); φ_kᵒ + α] for the centroid's move u and turn α is nearly linear; R =
  /// observed.cov + edge_noise carried into that frame. Gauss–Newton from options.start to convergence, the
  /// covariance from the last linearisation in Joseph form. Gating is the caller's job. *this is unchanged.
  /// @throw std::invalid_argument for no observations, non-finite input, a singular innovation covariance;
  ///        std::out_of_range for a bad edge index.
  RigidObject updated(std::span<const EdgeObservation> observations, const RigidUpdateOptions& options = {}) const;
  /// updated() with one line matched to edge k.
  RigidObject updated(std::size_t k, const LineFeature& observed, const Eigen::Matrix2d& edge_noise) const;

  /// The same object with its pose covariance widened to cover a move to `found` (a pose seen far outside the
  /// current uncertainty: the object was carried): diag(Δc_x², Δc_y², Δθ²) of the centroid's move is added. The
  /// pose itself stays; an update started at `found` then follows the data, not the old pose.
  /// @throw std::invalid_argument for a non-finite pose.
  RigidObject with_move_allowed(const Pose2D& found) const;

 private:
  Pose2D pose_;
  Eigen::Matrix3d pose_cov_;
  std::vector<LocalEdge> edges_;
};

/// Limits of find_by_shape.
struct ShapeFitOptions {
  double max_offset_m = 0.05;      // an explained segment's ends from its edge's line
  double max_angle_rad = 0.087;    // its direction from the edge's (5°)
  double max_overhang_m = 0.10;    // how far it may run past the edge's ends
  double max_shift_m = 3.0;        // how far the centroid may have moved
  double min_crossing_rad = 0.35;  // two seed segments must cross at least this much (20°)
  std::size_t max_seeds = 8;       // the longest segments seed hypotheses
  std::size_t max_edges = 32;      // objects with more edges are not searched
  std::size_t min_explained = 2;   // segments the pose must explain
};

/// A pose at which an object's edges explain observed segments.
struct ShapeFit {
  Pose2D pose;
  std::vector<std::optional<std::size_t>> edge_of;  // per observed segment: the edge it lies on, if any
  std::size_t explained = 0;
  double explained_length_m = 0.0;
  double rms_offset_m = 0.0;  // of the explained segments' ends from their edges' lines
};

/// Finds an object that has moved beyond its gate by its shape: pairs two crossing observed segments with two
/// edges at the same angle, solves the rigid transform (the crossing point and the directions), refines it on the
/// segments' ends and keeps the pose that explains the most observed length: a segment is explained when it lies
/// on one edge (offset, angle) and within its extent (so a wall much longer than an edge, or running past it, is
/// not the object). Of poses explaining the same, the one closest to the current pose (the symmetric twin of a
/// rectangle is half a turn away). Bounded: max_seeds² · edges² hypotheses. nullopt when fewer than
/// min_explained segments are explained, or the object has more than max_edges edges.
/// @throw std::invalid_argument for non-finite segments.
std::optional<ShapeFit> find_by_shape(const RigidObject& object, std::span<const LineSegment> observed,
                                      const ShapeFitOptions& options = {});

}  // namespace wm::fusion
