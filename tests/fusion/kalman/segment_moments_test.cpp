#include "fusion/kalman/segment_moments.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace wm::fusion {
namespace {

LineSegment seg(Eigen::Vector2d a, Eigen::Vector2d b) {
  return LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
}

TEST(SegmentMomentsTest, CollinearPiecesLieOnOneLine) {
  const auto m = SegmentMoments::of(seg({0, 1}, {2, 1})) + SegmentMoments::of(seg({3, 1}, {7, 1}));
  EXPECT_NEAR(m.weight, 6.0, 1e-12);
  EXPECT_NEAR(m.rms_offset_m(), 0.0, 1e-6);
}

TEST(SegmentMomentsTest, TwoParallelViewsSpreadByHalfTheirDistance) {
  // Equal lengths 4 cm apart: every point is 2 cm from the middle line.
  const auto m = SegmentMoments::of(seg({0, 0}, {3, 0})) + SegmentMoments::of(seg({0, 0.04}, {3, 0.04}));
  EXPECT_NEAR(m.rms_offset_m(), 0.02, 1e-9);
}

TEST(SegmentMomentsTest, FarFromTheOriginTheSpreadIsStillCentimetres) {
  // 5 km out, in any direction: the second moments are ~10⁷ m², the spread 1e-4 m².
  const Eigen::Vector2d far(3000.0, -4000.0);
  const Eigen::Vector2d along = Eigen::Vector2d(1, 2).normalized(), across(-along.y(), along.x());
  const auto m = SegmentMoments::of(seg(far, far + 3 * along)) +
                 SegmentMoments::of(seg(far + 0.02 * across, far + 0.02 * across + 3 * along));
  EXPECT_NEAR(m.rms_offset_m(), 0.01, 1e-4);
}

TEST(SegmentMomentsTest, DistanceFromAGivenLine) {
  // A segment 10 cm above the x axis, and one crossing it from −0.1 to +0.1: RMS 0.1 and 0.1/√3.
  const LineFeature x_axis{0.0, std::numbers::pi / 2, Eigen::Matrix2d::Identity()};
  EXPECT_NEAR(SegmentMoments::of(seg({2, 0.1}, {5, 0.1})).rms_offset_from_m(x_axis), 0.1, 1e-9);
  EXPECT_NEAR(SegmentMoments::of(seg({2, -0.1}, {5, 0.1})).rms_offset_from_m(x_axis), 0.1 / std::sqrt(3.0), 1e-9);
  EXPECT_EQ(SegmentMoments{}.rms_offset_from_m(x_axis), 0.0);
}

TEST(SegmentMomentsTest, StoredFormRoundTripsAndEmptyIsZero) {
  const auto m = SegmentMoments::of(seg({1, 2}, {4, 6}));
  const auto back = SegmentMoments::from_array(m.to_array());
  EXPECT_EQ(back.to_array(), m.to_array());
  EXPECT_EQ(SegmentMoments{}.rms_offset_m(), 0.0);
}

}  // namespace
}  // namespace wm::fusion
