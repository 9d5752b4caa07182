#include "fusion/registration/scan_alignment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <tuple>

#include "fusion/lines/scan_lines.h"
#include "tools/raycast/raycast.h"

namespace wm::fusion {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

// The lines of the map (world frame), known to σ across their middle and in direction (default: a surveyed plan).
std::vector<AlignmentReference> references_of(const std::vector<raycast::PlanLine>& walls,
                                              double sigma_offset_m = 0.001, double sigma_angle_rad = 0.01 * kDeg) {
  std::vector<AlignmentReference> references;
  for (const auto& wall : walls) {
    const auto shape = LineSegment::from_points(wall.p0, wall.p1, Eigen::Matrix2d::Identity());
    Eigen::Matrix2d j;
    j << 1, 0.5 * (shape.t0_m + shape.t1_m), 0, 1;
    const Eigen::Matrix2d cov =
        j * Eigen::Vector2d(sigma_offset_m * sigma_offset_m, sigma_angle_rad * sigma_angle_rad).asDiagonal() *
        j.transpose();
    references.push_back({LineSegment::from_points(wall.p0, wall.p1, cov), std::nullopt});
  }
  return references;
}

// One 0.5° scan with 1 cm range noise from the true pose, its lines in the sensor's own frame.
std::vector<LineSegment> scan_lines_from(const std::vector<raycast::PlanLine>& walls, const Pose2D& truth,
                                         unsigned seed = 3) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<RangeReading> readings;
  for (int i = 0; i < 720; ++i) {
    const double bearing = -std::numbers::pi + i * 0.5 * kDeg;
    const Eigen::Vector2d dir(std::cos(truth.theta_rad + bearing), std::sin(truth.theta_rad + bearing));
    const double r = raycast::cast_ray(walls, Eigen::Vector2d(truth.x_m, truth.y_m), dir, 20.0);
    if (std::isfinite(r)) readings.push_back({r + noise(rng), bearing});
  }
  return extract_scan_lines(readings, Pose2D{}, Eigen::Matrix3d::Zero(), ScanLineOptions{});
}

Eigen::Matrix3d pose_cov(double sigma_xy_m, double sigma_theta_rad) {
  return Eigen::Vector3d(sigma_xy_m * sigma_xy_m, sigma_xy_m * sigma_xy_m, sigma_theta_rad * sigma_theta_rad)
      .asDiagonal();
}

// An 8 × 6 m room with an inner wall and a pillar: directions in x and y, enough to fix all three.
std::vector<raycast::PlanLine> room() {
  using V = Eigen::Vector2d;
  return {{V(0, 0), V(8, 0)},       {V(8, 0), V(8, 6)},       {V(8, 6), V(0, 6)},
          {V(0, 6), V(0, 0)},       {V(5, 0), V(5, 3)},       {V(2, 4), V(2.6, 4)},
          {V(2.6, 4), V(2.6, 4.6)}, {V(2.6, 4.6), V(2, 4.6)}, {V(2, 4.6), V(2, 4)}};
}

TEST(ScanAlignmentTest, APostedPoseOffByTheHighNoiseLevelComesBackToWithinMillimetres) {
  const auto walls = room();
  const Pose2D truth{3.0, 2.0, 0.3};
  const auto local = scan_lines_from(walls, truth);
  ASSERT_GE(local.size(), 5u);
  const Eigen::Matrix3d cov = pose_cov(0.03, 0.5 * kDeg);
  for (const auto& [dx, dy, dtheta] :
       {std::tuple{0.04, -0.03, 0.6 * kDeg}, std::tuple{-0.05, 0.05, -0.8 * kDeg}, std::tuple{0.0, 0.06, 0.9 * kDeg}}) {
    const Pose2D posted{truth.x_m + dx, truth.y_m + dy, truth.theta_rad + dtheta};
    const auto result = align_scan_lines(local, posted, cov, references_of(walls));
    ASSERT_TRUE(result.aligned);
    EXPECT_GE(result.pairs, 5u);
    EXPECT_NEAR(result.pose.x_m, truth.x_m, 0.005);
    EXPECT_NEAR(result.pose.y_m, truth.y_m, 0.005);
    EXPECT_NEAR(result.pose.theta_rad, truth.theta_rad, 0.05 * kDeg);
    // The lines told it more than the posted covariance did.
    EXPECT_LT(result.cov(0, 0), 0.25 * cov(0, 0));
    EXPECT_LT(result.cov(2, 2), 0.25 * cov(2, 2));
  }
}

TEST(ScanAlignmentTest, AMapKnownNoBetterThanThePoseMovesItHalfWay) {
  // The map's lines share the error of the poses that placed them: however many of them pair, they tell where the
  // scan is against the map, and the map is known to σ 3 cm / 0.5° itself. Prior and map weigh the same.
  const auto walls = room();
  const Pose2D truth{3.0, 2.0, 0.3};
  const auto local = scan_lines_from(walls, truth);
  const Pose2D posted{truth.x_m + 0.04, truth.y_m - 0.04, truth.theta_rad + 0.8 * kDeg};
  const auto result =
      align_scan_lines(local, posted, pose_cov(0.03, 0.5 * kDeg), references_of(walls, 0.03, 0.5 * kDeg));
  ASSERT_TRUE(result.aligned);
  EXPECT_NEAR(result.pose.theta_rad - truth.theta_rad, 0.4 * kDeg, 0.1 * kDeg);
  EXPECT_NEAR(result.pose.x_m - truth.x_m, 0.02, 0.01);
  EXPECT_NEAR(result.pose.y_m - truth.y_m, -0.02, 0.01);
  EXPECT_NEAR(result.cov(2, 2), 0.5 * std::pow(0.5 * kDeg, 2), 0.1 * std::pow(0.5 * kDeg, 2));
}

TEST(ScanAlignmentTest, ACorridorFixesThePoseAcrossItAndTheHeadingButNotAlongIt) {
  using V = Eigen::Vector2d;
  const std::vector<raycast::PlanLine> walls = {{V(-30, 0), V(30, 0)}, {V(-30, 2), V(30, 2)}};
  const Pose2D truth{0.0, 0.8, 0.0};
  const auto local = scan_lines_from(walls, truth);
  const Pose2D posted{0.05, 0.84, 0.5 * kDeg};
  const auto result = align_scan_lines(local, posted, pose_cov(0.03, 0.5 * kDeg), references_of(walls));
  ASSERT_TRUE(result.aligned);
  EXPECT_NEAR(result.pose.y_m, truth.y_m, 0.005);
  EXPECT_NEAR(result.pose.theta_rad, truth.theta_rad, 0.05 * kDeg);
  EXPECT_NEAR(result.pose.x_m, posted.x_m, 0.002);  // nothing says where along the corridor it is
  EXPECT_NEAR(result.cov(0, 0), 0.03 * 0.03, 1e-5);
}

TEST(ScanAlignmentTest, AnExactPoseAGuessOrOneWithoutEnoughLinesStaysAsPosted) {
  const auto walls = room();
  const Pose2D truth{3.0, 2.0, 0.3};
  const auto local = scan_lines_from(walls, truth);
  const Pose2D posted{3.04, 2.0, 0.3};
  const auto exact = align_scan_lines(local, posted, Eigen::Matrix3d::Zero(), references_of(walls));
  EXPECT_FALSE(exact.aligned);
  EXPECT_EQ(exact.pose.x_m, posted.x_m);

  const auto guess = align_scan_lines(local, posted, pose_cov(0.6, 0.5 * kDeg), references_of(walls));
  EXPECT_FALSE(guess.aligned) << "σ 0.6 m: a guess, not an estimate to correct";
  EXPECT_FALSE(align_scan_lines(local, posted, pose_cov(0.03, 11 * kDeg), references_of(walls)).aligned);

  const auto no_map = align_scan_lines(local, posted, pose_cov(0.03, 0.5 * kDeg), {});
  EXPECT_FALSE(no_map.aligned);
  EXPECT_EQ(no_map.pose.x_m, posted.x_m);
  EXPECT_EQ(no_map.cov, pose_cov(0.03, 0.5 * kDeg));
}

TEST(ScanAlignmentTest, AMapThatDisagreesBeyondThePosesUncertaintyMovesNothing) {
  // The map's walls all lie 0.5 m off where the scan puts them: no pair passes the gate of a 3 cm pose.
  auto walls = room();
  const Pose2D truth{3.0, 2.0, 0.3};
  const auto local = scan_lines_from(walls, truth);
  for (auto& wall : walls) {
    wall.p0 += Eigen::Vector2d(0.5, 0.5);
    wall.p1 += Eigen::Vector2d(0.5, 0.5);
  }
  const auto result = align_scan_lines(local, truth, pose_cov(0.03, 0.5 * kDeg), references_of(walls));
  EXPECT_FALSE(result.aligned);
  EXPECT_EQ(result.pose.x_m, truth.x_m);
  EXPECT_EQ(result.pose.y_m, truth.y_m);
}

TEST(ScanAlignmentTest, TheFaceOfAThinWallTurnedAwayIsNeverAPartner) {
  // Two faces of a wall 6 cm thick; the robot stands below it and sees only the lower face (y = 3). The map also
  // holds the upper face (y = 3.06), facing up. Posted 3 cm low, the scan's line would lie nearer the upper face.
  using V = Eigen::Vector2d;
  const std::vector<raycast::PlanLine> seen = {{V(-10, 3), V(10, 3)}, {V(-3, -10), V(-3, 10)}};
  const Pose2D truth{0.0, 0.0, 0.0};
  const auto local = scan_lines_from(seen, truth);
  auto references = references_of(seen);
  references[0].facing_rad = -std::numbers::pi / 2;  // the lower face faces down
  auto upper = references_of({{V(-10, 3.06), V(10, 3.06)}});
  upper[0].facing_rad = std::numbers::pi / 2;
  references.push_back(upper[0]);
  const Pose2D posted{0.0, 0.04, 0.0};
  const auto result = align_scan_lines(local, posted, pose_cov(0.03, 0.5 * kDeg), references);
  ASSERT_TRUE(result.aligned);
  EXPECT_NEAR(result.pose.y_m, 0.0, 0.005);
}

TEST(ScanAlignmentTest, BadInputIsRefused) {
  const auto walls = room();
  const auto local = scan_lines_from(walls, Pose2D{3.0, 2.0, 0.3});
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(align_scan_lines(local, Pose2D{nan, 2.0, 0.3}, pose_cov(0.03, 0.01), references_of(walls)),
               std::invalid_argument);
  Eigen::Matrix3d asymmetric = pose_cov(0.03, 0.01);
  asymmetric(0, 1) = 1e-3;
  EXPECT_THROW(align_scan_lines(local, Pose2D{3.0, 2.0, 0.3}, asymmetric, references_of(walls)), std::invalid_argument);
  Eigen::Matrix3d negative = pose_cov(0.03, 0.01);
  negative(2, 2) = -1e-3;
  EXPECT_THROW(align_scan_lines(local, Pose2D{3.0, 2.0, 0.3}, negative, references_of(walls)), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
