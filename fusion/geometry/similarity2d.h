#pragma once

#include <Eigen/Core>

#include "fusion/geometry/pose2d.h"

namespace wm::fusion {

/// A 2-D similarity: where a drawing's frame sits in the world. A point p of the drawing is at
/// scale·R(θ)·p + (x, y) in the world. A plain value; scale > 0 is the caller's to keep.
struct Similarity2D {
  double x_m = 0.0;
  double y_m = 0.0;
  double theta_rad = 0.0;
  double scale = 1.0;

  Eigen::Vector2d transform_point(const Eigen::Vector2d& p) const;
  Eigen::Vector2d inverse_transform_point(const Eigen::Vector2d& world) const;
  /// A pose drawn in the drawing's frame, in the world: its position maps as a point, its heading turns by θ.
  Pose2D transform_pose(const Pose2D& drawn) const;
  Pose2D inverse_transform_pose(const Pose2D& world) const;
  /// The similarity that applies `first`, then this one.
  Similarity2D after(const Similarity2D& first) const;
  bool is_identity() const { return x_m == 0 && y_m == 0 && theta_rad == 0 && scale == 1; }
  bool operator==(const Similarity2D&) const = default;
};

}  // namespace wm::fusion
