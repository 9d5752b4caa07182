#include "fusion/geometry/pose2d.h"

#include <Eigen/Geometry>

namespace wm::fusion {

Eigen::Vector2d Pose2D::transform_point(const Eigen::Vector2d& local) const {
  return Eigen::Rotation2Dd(theta_rad) * local + Eigen::Vector2d(x_m, y_m);
}

Eigen::Vector2d Pose2D::inverse_transform_point(const Eigen::Vector2d& world) const {
  return Eigen::Rotation2Dd(theta_rad).inverse() * (world - Eigen::Vector2d(x_m, y_m));
}

}  // namespace wm::fusion
