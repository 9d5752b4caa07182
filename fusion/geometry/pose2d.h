#pragma once

#include <Eigen/Core>

namespace wm::fusion {

/// Pose of a frame in its parent (world) frame: position [m] and heading [rad], θ counter-clockwise from the
/// parent's x axis. A plain value; θ is not required to be wrapped.
struct Pose2D {
  double x_m = 0.0;
  double y_m = 0.0;
  double theta_rad = 0.0;

  /// Maps a point from this pose's local frame into the parent (world) frame [m]: R(θ)·local + (x, y).
  Eigen::Vector2d transform_point(const Eigen::Vector2d& local) const;
  /// Inverse of transform_point [m]: R(θ)ᵀ·(world − (x, y)).
  Eigen::Vector2d inverse_transform_point(const Eigen::Vector2d& world) const;
};

}  // namespace wm::fusion
