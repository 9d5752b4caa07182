#include "fusion/geometry/similarity2d.h"

#include <Eigen/Geometry>

namespace wm::fusion {

Eigen::Vector2d Similarity2D::transform_point(const Eigen::Vector2d& p) const {
  return scale * (Eigen::Rotation2Dd(theta_rad) * p) + Eigen::Vector2d(x_m, y_m);
}

Eigen::Vector2d Similarity2D::inverse_transform_point(const Eigen::Vector2d& world) const {
  return Eigen::Rotation2Dd(theta_rad).inverse() * (world - Eigen::Vector2d(x_m, y_m)) / scale;
}

Pose2D Similarity2D::transform_pose(const Pose2D& drawn) const {
  const auto p = transform_point({drawn.x_m, drawn.y_m});
  return {p.x(), p.y(), drawn.theta_rad + theta_rad};
}

Pose2D Similarity2D::inverse_transform_pose(const Pose2D& world) const {
  const auto p = inverse_transform_point({world.x_m, world.y_m});
  return {p.x(), p.y(), world.theta_rad - theta_rad};
}

Similarity2D Similarity2D::after(const Similarity2D& first) const {
  const auto t = transform_point({first.x_m, first.y_m});
  return {t.x(), t.y(), theta_rad + first.theta_rad, scale * first.scale};
}

}  // namespace wm::fusion
