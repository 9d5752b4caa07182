#include "fusion/geometry/pose2d.h"

#include <gtest/gtest.h>

#include <numbers>
#include <random>

namespace wm::fusion {
namespace {

TEST(Pose2DTest, TransformPointRotatesThenTranslates) {
  const Pose2D pose{1.0, 2.0, std::numbers::pi / 2.0};
  const Eigen::Vector2d p = pose.transform_point({1.0, 0.0});
  EXPECT_NEAR(p.x(), 1.0, 1e-15);
  EXPECT_NEAR(p.y(), 3.0, 1e-15);
  const Eigen::Vector2d q = pose.transform_point({0.0, 2.0});
  EXPECT_NEAR(q.x(), -1.0, 1e-15);
  EXPECT_NEAR(q.y(), 2.0, 1e-15);
}

TEST(Pose2DTest, DefaultPoseIsIdentity) {
  const Pose2D pose;
  EXPECT_EQ(pose.transform_point({0.3, -4.0}), Eigen::Vector2d(0.3, -4.0));
}

TEST(Pose2DTest, InverseTransformUndoesTransform) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  for (int i = 0; i < 100; ++i) {
    const Pose2D pose{u(rng), u(rng), u(rng)};
    const Eigen::Vector2d local(u(rng), u(rng));
    const Eigen::Vector2d world = pose.transform_point(local);
    EXPECT_NEAR((pose.inverse_transform_point(world) - local).norm(), 0.0, 1e-13);
    // Distances from the pose origin are preserved by a rigid transform.
    EXPECT_NEAR((world - Eigen::Vector2d(pose.x_m, pose.y_m)).norm(), local.norm(), 1e-12);
  }
}

}  // namespace
}  // namespace wm::fusion
