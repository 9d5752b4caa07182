#include "fusion/geometry/line.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "tests/fusion/fusion_test_helpers.h"

namespace wm::fusion {
namespace {

constexpr double kPi = std::numbers::pi;

Eigen::Matrix2d cov2(double a, double b, double c) { return (Eigen::Matrix2d() << a, b, b, c).finished(); }

TEST(LineFeatureTest, NormalizedFlipsNegativeRhoAndNegatesCrossCovariance) {
  const LineFeature line{-2.0, 0.3, cov2(0.01, 0.002, 0.04)};
  const LineFeature n = line.normalized();
  EXPECT_DOUBLE_EQ(n.rho_m, 2.0);
  EXPECT_NEAR(n.phi_rad, 0.3 - kPi, 1e-15);
  EXPECT_DOUBLE_EQ(n.cov(0, 0), 0.01);
  EXPECT_DOUBLE_EQ(n.cov(1, 1), 0.04);
  EXPECT_DOUBLE_EQ(n.cov(0, 1), -0.002);
  EXPECT_DOUBLE_EQ(n.cov(1, 0), -0.002);
  // Both representations describe the same points.
  const Eigen::Vector2d p = 5.0 * line.direction() + line.rho_m * line.normal();
  EXPECT_NEAR(n.signed_distance(p), 0.0, 1e-14);
}

TEST(LineFeatureTest, NormalizedWrapsPhiAndKeepsPositiveRho) {
  const LineFeature n = LineFeature{1.5, 1.5 * kPi, cov2(0.01, 0.002, 0.04)}.normalized();
  EXPECT_DOUBLE_EQ(n.rho_m, 1.5);
  EXPECT_NEAR(n.phi_rad, -0.5 * kPi, 1e-15);
  EXPECT_DOUBLE_EQ(n.cov(0, 1), 0.002);
  EXPECT_EQ(LineFeature({1.0, -kPi}).normalized().phi_rad, kPi);
}

TEST(LineFeatureTest, NormalizedTurnsNegativeZeroRhoIntoPositiveZero) {
  const LineFeature n = LineFeature{-0.0, 0.5}.normalized();
  EXPECT_FALSE(std::signbit(n.rho_m));
  EXPECT_DOUBLE_EQ(n.phi_rad, 0.5);
}

TEST(LineFeatureTest, NormalizedSymmetrisesCovariance) {
  const LineFeature n = LineFeature{1.0, 0.0, (Eigen::Matrix2d() << 1.0, 0.2, 0.4, 2.0).finished()}.normalized();
  EXPECT_DOUBLE_EQ(n.cov(0, 1), 0.3);
  EXPECT_DOUBLE_EQ(n.cov(1, 0), 0.3);
}

TEST(LineFeatureTest, DistanceAndCoordinateFollowTheNormalAndDirection) {
  const LineFeature line{2.0, kPi / 2.0};  // y = 2, normal +y, direction −x
  EXPECT_NEAR(line.normal().x(), 0.0, 1e-16);
  EXPECT_NEAR(line.normal().y(), 1.0, 1e-16);
  EXPECT_NEAR(line.direction().x(), -1.0, 1e-16);
  EXPECT_NEAR(line.direction().y(), 0.0, 1e-16);
  EXPECT_NEAR(line.signed_distance({3.0, 5.0}), 3.0, 1e-15);
  EXPECT_NEAR(line.signed_distance({3.0, -1.0}), -3.0, 1e-15);
  EXPECT_NEAR(line.coordinate_along({3.0, 5.0}), -3.0, 1e-15);
}

TEST(LineSegmentTest, FromPointsOrdersExtentAndReproducesTheEndpoints) {
  const Eigen::Matrix2d cov = cov2(1e-4, 2e-6, 4e-4);
  const LineSegment s = LineSegment::from_points({4.0, 1.0}, {1.0, 1.0}, cov);
  EXPECT_NEAR(s.line.rho_m, 1.0, 1e-15);
  EXPECT_NEAR(s.line.phi_rad, kPi / 2.0, 1e-15);
  EXPECT_LE(s.t0_m, s.t1_m);
  EXPECT_NEAR(s.t0_m, -4.0, 1e-15);  // direction is −x, so (4, 1) comes first
  EXPECT_NEAR(s.t1_m, -1.0, 1e-15);
  EXPECT_NEAR((s.p0() - Eigen::Vector2d(4.0, 1.0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((s.p1() - Eigen::Vector2d(1.0, 1.0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR(s.length_m(), 3.0, 1e-15);
  EXPECT_EQ(s.line.cov, cov);
}

TEST(LineSegmentTest, FromPointsGivesNonNegativeRhoOnBothSidesOfTheOrigin) {
  const Eigen::Matrix2d cov = cov2(1e-4, 0.0, 1e-4);
  const LineSegment left = LineSegment::from_points({-2.0, 0.0}, {-2.0, 3.0}, cov);  // x = −2
  EXPECT_NEAR(left.line.rho_m, 2.0, 1e-15);
  EXPECT_NEAR(left.line.phi_rad, kPi, 1e-15);
  const LineSegment right = LineSegment::from_points({2.0, 3.0}, {2.0, 0.0}, cov);  // x = 2
  EXPECT_NEAR(right.line.rho_m, 2.0, 1e-15);
  EXPECT_NEAR(right.line.phi_rad, 0.0, 1e-15);
  EXPECT_NEAR(right.length_m(), 3.0, 1e-15);
  const LineSegment through_origin = LineSegment::from_points({-1.0, -1.0}, {2.0, 2.0}, cov);
  EXPECT_GE(through_origin.line.rho_m, 0.0);
  EXPECT_NEAR(through_origin.line.rho_m, 0.0, 1e-15);
  EXPECT_NEAR(through_origin.length_m(), 3.0 * std::sqrt(2.0), 1e-14);
}

TEST(LineSegmentTest, FromPointsRejectsBadInput) {
  const Eigen::Matrix2d ok = cov2(1e-4, 0.0, 1e-4);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(LineSegment::from_points({1.0, 1.0}, {1.0, 1.0 + 1e-10}, ok), std::invalid_argument);
  EXPECT_THROW(LineSegment::from_points({nan, 1.0}, {1.0, 2.0}, ok), std::invalid_argument);
  EXPECT_THROW(LineSegment::from_points({0.0, 1.0}, {1.0, 2.0}, cov2(1e-4, nan, 1e-4)), std::invalid_argument);
  EXPECT_THROW(LineSegment::from_points({0.0, 1.0}, {1.0, 2.0}, cov2(1e-4, 2e-4, 1e-4)), std::invalid_argument);
  EXPECT_THROW(LineSegment::from_points({0.0, 1.0}, {1.0, 2.0}, Eigen::Matrix2d::Zero()), std::invalid_argument);
  const Eigen::Matrix2d asymmetric = (Eigen::Matrix2d() << 1e-4, 1e-6, 2e-6, 1e-4).finished();
  EXPECT_THROW(LineSegment::from_points({0.0, 1.0}, {1.0, 2.0}, asymmetric), std::invalid_argument);
  try {
    LineSegment::from_points({0.0, 0.0}, {0.0, 0.0}, ok);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("from_points"), std::string::npos);
  }
}

// World (ρ, φ) computed from two transformed points of the local line, aligned next to reference_phi.
Eigen::Vector2d world_line_from_points(const Eigen::Matrix<double, 5, 1>& v, double reference_phi) {
  const LineFeature local{v(0), v(1)};
  const Pose2D pose{v(2), v(3), v(4)};
  const Eigen::Vector2d a = local.rho_m * local.normal() - 1.0 * local.direction();
  const Eigen::Vector2d b = local.rho_m * local.normal() + 2.0 * local.direction();
  return testing::line_through(pose.transform_point(a), pose.transform_point(b), reference_phi);
}

void expect_transform_matches_numeric(const LineFeature& local, const Pose2D& pose, const Eigen::Matrix3d& pose_cov) {
  const LineFeature world = transform_line(local, pose, pose_cov);
  ASSERT_GE(world.rho_m, 0.0);
  ASSERT_GT(world.phi_rad, -kPi);
  ASSERT_LE(world.phi_rad, kPi);

  Eigen::Matrix<double, 5, 1> v;
  v << local.rho_m, local.phi_rad, pose.x_m, pose.y_m, pose.theta_rad;
  const Eigen::Vector2d reference = world_line_from_points(v, world.phi_rad);
  EXPECT_NEAR(world.rho_m, reference(0), 1e-12);
  EXPECT_NEAR(world.phi_rad, reference(1), 1e-12);

  const auto f = [&](const Eigen::Matrix<double, 5, 1>& x) { return world_line_from_points(x, world.phi_rad); };
  const Eigen::Matrix<double, 2, 5> j = testing::numeric_jacobian<2>(f, v);
  Eigen::Matrix<double, 5, 5> joint = Eigen::Matrix<double, 5, 5>::Zero();
  joint.topLeftCorner<2, 2>() = local.cov;
  joint.bottomRightCorner<3, 3>() = pose_cov;
  const Eigen::Matrix2d expected = j * joint * j.transpose();
  EXPECT_NEAR((world.cov - expected).cwiseAbs().maxCoeff(), 0.0, 1e-9 * expected.cwiseAbs().maxCoeff())
      << "analytic\n"
      << world.cov << "\nnumeric\n"
      << expected;
}

TEST(TransformLineTest, CovarianceMatchesNumericJacobianOfTransformedPoints) {
  const LineFeature local{1.2, 0.4, cov2(1e-4, 3e-5, 4e-4)};
  const Eigen::Matrix3d pose_cov =
      (Eigen::Matrix3d() << 4e-3, 1e-3, 5e-4, 1e-3, 2e-3, -3e-4, 5e-4, -3e-4, 1e-3).finished();
  expect_transform_matches_numeric(local, Pose2D{3.0, -1.5, 0.7}, pose_cov);
}

TEST(TransformLineTest, NormalizesWhenTheWorldLinePassesBehindTheOrigin) {
  // The raw formula gives ρ_w = 1 + (−4)·1 < 0 here, so the result must be flipped, cross term included.
  const LineFeature local{1.0, 0.0, cov2(1e-4, 3e-5, 4e-4)};
  const Pose2D pose{-4.0, 0.5, 0.0};
  const Eigen::Matrix3d pose_cov = Eigen::Vector3d(1e-3, 2e-3, 5e-4).asDiagonal();
  const LineFeature world = transform_line(local, pose, pose_cov);
  EXPECT_NEAR(world.rho_m, 3.0, 1e-14);
  EXPECT_NEAR(world.phi_rad, kPi, 1e-14);
  expect_transform_matches_numeric(local, pose, pose_cov);
}

TEST(TransformLineTest, AcceptsEitherLocalRepresentation) {
  const LineFeature local{0.8, -2.5, cov2(1e-4, -2e-5, 3e-4)};
  const LineFeature flipped{-0.8, -2.5 + kPi, cov2(1e-4, 2e-5, 3e-4)};
  const Pose2D pose{0.5, 2.0, -1.1};
  const Eigen::Matrix3d pose_cov = Eigen::Vector3d(1e-3, 2e-3, 5e-4).asDiagonal();
  const LineFeature a = transform_line(local, pose, pose_cov);
  const LineFeature b = transform_line(flipped, pose, pose_cov);
  EXPECT_NEAR(a.rho_m, b.rho_m, 1e-14);
  EXPECT_NEAR(a.phi_rad, b.phi_rad, 1e-14);
  EXPECT_NEAR((a.cov - b.cov).norm(), 0.0, 1e-17);
  expect_transform_matches_numeric(local, pose, pose_cov);
}

TEST(TransformLineTest, RejectsNonFiniteInput) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(transform_line({nan, 0.0}, Pose2D{}, Eigen::Matrix3d::Zero()), std::invalid_argument);
  EXPECT_THROW(transform_line({1.0, 0.0}, Pose2D{nan, 0.0, 0.0}, Eigen::Matrix3d::Zero()), std::invalid_argument);
  EXPECT_THROW(transform_line({1.0, 0.0}, Pose2D{}, Eigen::Matrix3d::Constant(nan)), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
