#include "fusion/kalman/line_map.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "fusion/geometry/angle.h"
#include "tests/fusion/fusion_test_helpers.h"

namespace wm::fusion {
namespace {

constexpr double kPi = std::numbers::pi;

const Eigen::Matrix2d kCov = Eigen::Vector2d(1e-4, 1e-4).asDiagonal();

Eigen::Matrix2d cov2(double a, double b, double c) { return (Eigen::Matrix2d() << a, b, b, c).finished(); }

LineSegment seg(Eigen::Vector2d a, Eigen::Vector2d b, const Eigen::Matrix2d& cov = kCov) {
  return LineSegment::from_points(a, b, cov);
}

// The other representation of a line, as a caller might hold it: (−ρ, φ+π) with cov(ρ, φ) negated.
LineFeature flip(const LineFeature& l) {
  const Eigen::Matrix2d f = Eigen::Vector2d(-1.0, 1.0).asDiagonal();
  return LineFeature{-l.rho_m, l.phi_rad + kPi, f * l.cov * f};
}

double hand_mahalanobis(const Eigen::Vector2d& delta, const Eigen::Matrix2d& cov) {
  return delta.dot(cov.inverse() * delta);
}

TEST(LineMapTest, DoorwayObservationMatchesOnlyTheWallItOverlaps) {
  // Two collinear walls at y = 3 with a 1 m doorway between x = 4 and x = 5.
  const std::vector<LineSegment> walls = {seg({0.0, 3.0}, {4.0, 3.0}), seg({5.0, 3.0}, {9.0, 3.0})};
  const MatchOptions options;
  const LineSegment seen = seg({1.0, 3.0}, {3.0, 3.0});
  EXPECT_NEAR(extent_gap_m(walls[0], seen), 0.0, 1e-15);
  EXPECT_NEAR(extent_gap_m(walls[1], seen), 2.0, 1e-14);
  const auto first = match_segment(walls[0], seen, options);
  ASSERT_TRUE(first.has_value());
  EXPECT_NEAR(first->mahalanobis_sq, 0.0, 1e-20);
  EXPECT_FALSE(match_segment(walls[1], seen, options).has_value());
  const auto best = best_match(walls, seen, options);
  ASSERT_TRUE(best.has_value());
  EXPECT_EQ(best->index, 0u);
}

TEST(LineMapTest, DoorwayObservationInTheGapMatchesNeitherWall) {
  const std::vector<LineSegment> walls = {seg({0.0, 3.0}, {4.0, 3.0}), seg({5.0, 3.0}, {9.0, 3.0})};
  const LineSegment seen = seg({4.5, 3.0}, {4.6, 3.0});
  EXPECT_NEAR(extent_gap_m(walls[0], seen), 0.5, 1e-14);
  EXPECT_NEAR(extent_gap_m(walls[1], seen), 0.4, 1e-14);
  EXPECT_FALSE(best_match(walls, seen, MatchOptions{}).has_value());
  // A smaller gap than max_gap_m still extends the first wall.
  const LineSegment near_end = seg({4.05, 3.0}, {4.3, 3.0});
  const auto best = best_match(walls, near_end, MatchOptions{});
  ASSERT_TRUE(best.has_value());
  EXPECT_EQ(best->index, 0u);
  MatchOptions small_gap;
  small_gap.max_gap_m = 0.04;
  EXPECT_FALSE(match_segment(walls[0], near_end, small_gap).has_value());
}

TEST(LineMapTest, DoorwayThroughTheOriginMatchesAReversedObservation) {
  // Walls on y = 0 (ρ = 0): the observation, given right-to-left, gets the other normal (φ = +π/2 vs −π/2).
  const std::vector<LineSegment> walls = {seg({0.0, 0.0}, {4.0, 0.0}), seg({5.0, 0.0}, {9.0, 0.0})};
  const LineSegment seen = seg({3.0, 0.0}, {1.0, 0.0});
  ASSERT_NEAR(std::abs(normalize_angle(walls[0].line.phi_rad - seen.line.phi_rad)), kPi, 1e-15);
  EXPECT_NEAR(extent_gap_m(walls[0], seen), 0.0, 1e-15);
  EXPECT_NEAR(extent_gap_m(walls[1], seen), 2.0, 1e-14);
  const auto best = best_match(walls, seen, MatchOptions{});
  ASSERT_TRUE(best.has_value());
  EXPECT_EQ(best->index, 0u);
  EXPECT_NEAR(best->mahalanobis_sq, 0.0, 1e-20);
}

TEST(LineMapTest, ExtentGapIsMeasuredOnTheElementsLine) {
  const LineSegment element = seg({0.0, 1.0}, {2.0, 1.0});
  // Tilted observation: its endpoints project to x = 2.3 and x = 3.0 on y = 1.
  const LineSegment observed = seg({3.0, 1.2}, {2.3, 1.1});
  EXPECT_NEAR(extent_gap_m(element, observed), 0.3, 1e-14);
  EXPECT_NEAR(extent_gap_m(element, seg({-0.5, 1.0}, {-0.2, 1.0})), 0.2, 1e-14);
  EXPECT_NEAR(extent_gap_m(element, seg({2.0, 1.0}, {3.0, 1.0})), 0.0, 1e-14);   // touching
  EXPECT_NEAR(extent_gap_m(element, seg({-1.0, 1.0}, {5.0, 1.0})), 0.0, 1e-14);  // containing
}

// Covariances far below the floors, so the floors are the tolerances.
const Eigen::Matrix2d kTight = Eigen::Vector2d(1e-8, 1e-10).asDiagonal();

TEST(LineMapTest, OffsetGateIsInclusiveAtTheFloor) {
  const MatchOptions options;
  const LineSegment element = seg({0.0, 2.0}, {4.0, 2.0}, kTight);
  const double limit = options.min_offset_m;
  const LineSegment inside = seg({1.0, 2.0 + limit * (1.0 - 1e-6)}, {3.0, 2.0 + limit * (1.0 - 1e-6)}, kTight);
  const LineSegment outside = seg({1.0, 2.0 + limit * (1.0 + 1e-6)}, {3.0, 2.0 + limit * (1.0 + 1e-6)}, kTight);
  const SegmentGate in = segment_gate(element, inside, options);
  EXPECT_TRUE(in.passes);
  EXPECT_NEAR(in.offset_m[0], limit * (1.0 - 1e-6), 1e-12);
  EXPECT_NEAR(in.offset_limit_m[1], limit, 1e-12);
  EXPECT_FALSE(segment_gate(element, outside, options).passes);
  // The reported d² is the (ρ, φ) innovation, far above any χ² bound with these covariances: it is not the gate.
  EXPECT_GT(match_segment(element, inside, options)->mahalanobis_sq, 1e3);
}

TEST(LineMapTest, OffsetToleranceGrowsWithTheCovarianceAtTheEnds) {
  // σ across the line at the ends of a 4 m segment centred on the origin's foot: C_ρρ + t²·C_φφ.
  MatchOptions options;
  options.min_offset_m = 0.0;
  const Eigen::Matrix2d cov = Eigen::Vector2d(1e-4, 1e-4).asDiagonal();  // σρ = 1 cm, σφ = 0.01 rad
  const LineSegment element = seg({-2.0, 1.0}, {2.0, 1.0}, cov);
  const LineSegment observed = seg({-2.0, 1.0}, {2.0, 1.0}, cov);
  const SegmentGate g = segment_gate(element, observed, options);
  const double sigma_end = std::sqrt(2.0 * (1e-4 + 4.0 * 1e-4));  // both lines, t = ±2 m
  EXPECT_NEAR(g.offset_limit_m[0], options.gate_sigmas * sigma_end, 1e-12);
  EXPECT_NEAR(g.offset_limit_m[1], options.gate_sigmas * sigma_end, 1e-12);
  EXPECT_NEAR(offset_variance_at(element.line, 2.0), 1e-4 + 4e-4, 1e-15);
}

TEST(LineMapTest, ShortViewsAFewDegreesOffAreTheSameWallButABendIsNot) {
  const MatchOptions options;  // 3 cm, 2° and atan(3 cm / length) floors
  const LineSegment wall = seg({0.0, 0.0}, {6.0, 0.0}, kTight);
  const auto tilted = [&](double cx, double half, double degrees) {
    const double a = degrees * kPi / 180.0;
    const Eigen::Vector2d d(std::cos(a), std::sin(a));
    return seg(Eigen::Vector2d(cx, 0.0) - half * d, Eigen::Vector2d(cx, 0.0) + half * d, kTight);
  };
  // 0.5 m seen 3° off: its direction is only known to atan(3 cm / 0.5 m) = 3.4°, its ends are 1.3 cm off.
  const SegmentGate short_view = segment_gate(wall, tilted(3.0, 0.25, 3.0), options);
  EXPECT_TRUE(short_view.passes);
  EXPECT_NEAR(short_view.angle_limit_rad, std::atan(0.03 / 0.5), 1e-12);
  // 4° is too much for 0.5 m, though its ends would pass; a 0.3 m view may turn 5°.
  const SegmentGate steep = segment_gate(wall, tilted(3.0, 0.25, 4.0), options);
  EXPECT_FALSE(steep.passes);
  EXPECT_LE(steep.offset_m[0], options.min_offset_m);
  EXPECT_TRUE(segment_gate(wall, tilted(3.0, 0.15, 5.0), options).passes);
  // Without the length floor only min_angle_rad (2°) is left.
  MatchOptions fixed = options;
  fixed.angle_floor_from_length = false;
  EXPECT_FALSE(segment_gate(wall, tilted(3.0, 0.25, 3.0), fixed).passes);
  // A wall that bends by 1.5° past the element's end: inside the 2° floor, but its far end is 5 cm off.
  const Eigen::Vector2d d(std::cos(1.5 * kPi / 180.0), std::sin(1.5 * kPi / 180.0));
  const LineSegment bend = seg({6.0, 0.0}, Eigen::Vector2d(6.0, 0.0) + 2.0 * d, kTight);
  const SegmentGate g = segment_gate(wall, bend, options);
  EXPECT_FALSE(g.passes);
  EXPECT_NEAR(g.offset_m[1], 2.0 * d.x() * d.y(), 1e-9);  // across the bend's own line
  EXPECT_LT(g.angle_rad, g.angle_limit_rad);
}

TEST(LineMapTest, MahalanobisWrapsTheAngleNearPi) {
  const LineFeature a{2.0, kPi - 0.01, kCov};
  const LineFeature b{2.0, -kPi + 0.01, kCov};
  EXPECT_NEAR(mahalanobis_squared(a, b), 0.02 * 0.02 / 2e-4, 1e-10);
  EXPECT_NEAR(mahalanobis_squared(b, a), 0.02 * 0.02 / 2e-4, 1e-10);
}

TEST(LineMapTest, MahalanobisUsesFullCovariance) {
  const LineFeature a{2.0, 0.5, cov2(1e-4, 3e-5, 2e-4)};
  const LineFeature b{2.03, 0.48, cov2(2e-4, -1e-5, 1e-4)};
  EXPECT_NEAR(mahalanobis_squared(a, b), hand_mahalanobis({0.03, -0.02}, a.cov + b.cov), 1e-10);
}

TEST(LineMapTest, MahalanobisTreatsBothRepresentationsAsTheSameLine) {
  const LineFeature a{0.01, 0.3, cov2(1e-4, 4e-5, 2e-4)};
  const LineFeature b{0.005, 0.31, cov2(2e-4, -3e-5, 1e-4)};
  const double expected = hand_mahalanobis({-0.005, 0.01}, a.cov + b.cov);
  EXPECT_NEAR(mahalanobis_squared(a, b), expected, 1e-10);
  EXPECT_NEAR(mahalanobis_squared(a, flip(b)), expected, 1e-10);
  EXPECT_NEAR(mahalanobis_squared(flip(a), b), expected, 1e-10);
  // Near the origin a close line can sit on the other side: its normalized form has φ ≈ 0.3 − π, and only
  // the flipped representation (with cov(ρ, φ) negated) compares it correctly.
  const LineFeature across = LineFeature{-0.004, 0.305, b.cov}.normalized();
  ASSERT_NEAR(across.phi_rad, 0.305 - kPi, 1e-15);
  EXPECT_NEAR(mahalanobis_squared(a, across), hand_mahalanobis({-0.014, 0.005}, a.cov + b.cov), 1e-10);
}

TEST(LineMapTest, MahalanobisRejectsSingularCovarianceSum) {
  EXPECT_THROW(mahalanobis_squared(LineFeature{1.0, 0.0}, LineFeature{1.0, 0.0}), std::invalid_argument);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(mahalanobis_squared(LineFeature{nan, 0.0, kCov}, LineFeature{1.0, 0.0, kCov}), std::invalid_argument);
}

TEST(LineMapTest, BestMatchPicksSmallestDistanceAndBreaksTiesByIndex) {
  const LineSegment observed = seg({0.0, 2.0}, {1.0, 2.0});
  const std::vector<LineSegment> candidates = {seg({0.0, 2.02}, {2.0, 2.02}), seg({0.0, 2.01}, {2.0, 2.01}),
                                               seg({0.0, 1.99}, {2.0, 1.99}), seg({0.0, 5.0}, {2.0, 5.0})};
  const auto best = best_match(candidates, observed, MatchOptions{});
  ASSERT_TRUE(best.has_value());
  EXPECT_EQ(best->index, 1u);  // 1 and 2 are equally close; the lower index wins
  EXPECT_NEAR(best->mahalanobis_sq, 0.01 * 0.01 / 2e-4, 1e-9);
  EXPECT_FALSE(best_match(std::vector<LineSegment>{}, observed, MatchOptions{}).has_value());
}

TEST(LineMapTest, FuseOfEqualCovariancesAveragesTheLines) {
  const LineSegment a{LineFeature{2.0, 0.10, kCov}, 0.0, 1.0};
  const LineSegment b{LineFeature{2.02, 0.12, kCov}, 0.5, 2.0};
  const LineSegment f = fuse(a, b);
  EXPECT_NEAR(f.line.rho_m, 2.01, 1e-14);
  EXPECT_NEAR(f.line.phi_rad, 0.11, 1e-14);
  EXPECT_NEAR((f.line.cov - kCov / 2.0).cwiseAbs().maxCoeff(), 0.0, 1e-19);
}

TEST(LineMapTest, FuseEqualsTheKalmanUpdateWithIdentityMeasurement) {
  const LineSegment a{LineFeature{2.0, 0.5, cov2(1e-4, 3e-5, 2e-4)}, 0.0, 1.0};
  const LineSegment b{LineFeature{2.03, 0.48, cov2(4e-4, -1e-5, 1e-4)}, 0.0, 1.0};
  const LineSegment f = fuse(a, b);
  const Eigen::Matrix2d gain = a.line.cov * (a.line.cov + b.line.cov).inverse();
  const Eigen::Vector2d expected = Eigen::Vector2d(2.0, 0.5) + gain * Eigen::Vector2d(0.03, -0.02);
  const Eigen::Matrix2d expected_cov = a.line.cov - gain * a.line.cov;
  EXPECT_NEAR(f.line.rho_m, expected.x(), 1e-14);
  EXPECT_NEAR(f.line.phi_rad, expected.y(), 1e-14);
  EXPECT_NEAR((f.line.cov - expected_cov).cwiseAbs().maxCoeff(), 0.0, 1e-18);
  EXPECT_EQ(f.line.cov(0, 1), f.line.cov(1, 0));
}

TEST(LineMapTest, FusedCovarianceIsSmallerThanBothInputs) {
  const LineSegment a{LineFeature{3.0, -1.0, cov2(1e-4, 3e-5, 2e-4)}, 0.0, 1.0};
  const LineSegment b{LineFeature{3.01, -1.01, cov2(3e-4, -8e-5, 5e-5)}, 0.0, 1.0};
  const LineSegment f = fuse(a, b);
  EXPECT_GT(testing::min_eigenvalue(Eigen::Matrix2d(a.line.cov - f.line.cov)), 0.0);
  EXPECT_GT(testing::min_eigenvalue(Eigen::Matrix2d(b.line.cov - f.line.cov)), 0.0);
  EXPECT_GT(testing::min_eigenvalue(f.line.cov), 0.0);
}

TEST(LineMapTest, FuseWrapsTheAngleAcrossPi) {
  const LineSegment a{LineFeature{2.0, kPi - 0.01, kCov}, 0.0, 1.0};
  const LineSegment b{LineFeature{2.0, -kPi + 0.03, kCov}, 0.0, 1.0};
  const LineSegment f = fuse(a, b);
  EXPECT_NEAR(f.line.rho_m, 2.0, 1e-14);
  EXPECT_NEAR(f.line.phi_rad, -kPi + 0.01, 1e-14);
}

TEST(LineMapTest, FuseExpressesTheObservationInTheElementsRepresentation) {
  // Element on y = 0 with φ = −π/2; the observation on y = 0.001 arrives as ρ = 0.001, φ = +π/2, which in the
  // element's representation is ρ = −0.001. The average, ρ = −0.0005 at φ = −π/2, normalizes to y = 0.0005.
  const LineSegment element = seg({0.0, 0.0}, {4.0, 0.0});
  ASSERT_NEAR(element.line.phi_rad, -kPi / 2.0, 1e-15);
  const LineSegment observed = seg({3.0, 0.001}, {1.0, 0.001});
  ASSERT_NEAR(observed.line.phi_rad, kPi / 2.0, 1e-15);
  const LineSegment f = fuse(element, observed);
  EXPECT_NEAR(f.line.rho_m, 0.0005, 1e-15);
  EXPECT_NEAR(f.line.phi_rad, kPi / 2.0, 1e-15);
  EXPECT_NEAR(f.t0_m, -4.0, 1e-14);  // direction −x
  EXPECT_NEAR(f.t1_m, 0.0, 1e-14);
  EXPECT_NEAR((f.line.cov - kCov / 2.0).cwiseAbs().maxCoeff(), 0.0, 1e-19);
  // Handing over the observation in its other representation changes nothing.
  const LineSegment same{flip(observed.line), -observed.t1_m, -observed.t0_m};
  const LineSegment g = fuse(element, same);
  EXPECT_NEAR(g.line.rho_m, f.line.rho_m, 1e-15);
  EXPECT_NEAR(g.line.phi_rad, f.line.phi_rad, 1e-15);
  EXPECT_NEAR(g.t0_m, f.t0_m, 1e-14);
  EXPECT_NEAR(g.t1_m, f.t1_m, 1e-14);
}

TEST(LineMapTest, FusedExtentIsTheUnionOfAllFourEndpoints) {
  const LineSegment a = seg({0.0, 2.0}, {2.0, 2.0});
  const LineSegment b = seg({3.5, 2.0}, {1.5, 2.0});
  const LineSegment f = fuse(a, b);
  EXPECT_NEAR(f.line.rho_m, 2.0, 1e-15);
  EXPECT_NEAR(f.line.phi_rad, kPi / 2.0, 1e-15);
  EXPECT_NEAR(f.length_m(), 3.5, 1e-14);
  EXPECT_NEAR((f.p0() - Eigen::Vector2d(3.5, 2.0)).norm(), 0.0, 1e-14);
  EXPECT_NEAR((f.p1() - Eigen::Vector2d(0.0, 2.0)).norm(), 0.0, 1e-14);
  // Disjoint but close extents are bridged as well.
  const LineSegment g = fuse(a, seg({2.05, 2.0}, {3.0, 2.0}));
  EXPECT_NEAR(g.length_m(), 3.0, 1e-14);
}

TEST(LineMapTest, RepeatedFusionStopsAtTheFloor) {
  // The same wall seen 200 times from one trajectory: without a floor the covariance would shrink 200-fold.
  const FusionOptions floor{0.01, 0.0044};
  LineSegment element = seg({1.0, 3.0}, {5.0, 3.0}, cov2(4e-4, 1e-5, 4e-5));
  for (int i = 0; i < 200; ++i) element = fuse(element, seg({1.0, 3.0}, {5.0, 3.0}, cov2(4e-4, 1e-5, 4e-5)), floor);
  // Midpoint form: σ across the line at the middle, σ of the direction.
  const double t_mid = 0.5 * (element.t0_m + element.t1_m);
  const Eigen::Matrix2d c = element.line.cov;
  const double offset_var = c(0, 0) - 2.0 * t_mid * c(0, 1) + t_mid * t_mid * c(1, 1);
  EXPECT_NEAR(offset_var, 0.01 * 0.01, 1e-10);
  EXPECT_NEAR(c(1, 1), 0.0044 * 0.0044, 1e-12);
  // A floor below the fused uncertainty changes nothing.
  const LineSegment a = seg({1.0, 3.0}, {5.0, 3.0}), b = seg({1.0, 3.01}, {5.0, 3.01});
  EXPECT_TRUE(fuse(a, b, FusionOptions{}).line.cov.isApprox(fuse(a, b).line.cov, 1e-12));
}

TEST(LineMapTest, FuseRejectsSingularCovariances) {
  const LineSegment good{LineFeature{2.0, 0.1, kCov}, 0.0, 1.0};
  const LineSegment singular{LineFeature{2.0, 0.1, cov2(1e-4, 1e-4, 1e-4)}, 0.0, 1.0};
  const LineSegment zero{LineFeature{2.0, 0.1, Eigen::Matrix2d::Zero()}, 0.0, 1.0};
  EXPECT_THROW(fuse(good, singular), std::invalid_argument);
  EXPECT_THROW(fuse(zero, good), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
