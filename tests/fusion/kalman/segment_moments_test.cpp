#include "fusion/kalman/segment_moments.h"

#include <gtest/gtest.h>

#include <cmath>

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

TEST(SegmentMomentsTest, StoredFormRoundTripsAndEmptyIsZero) {
  const auto m = SegmentMoments::of(seg({1, 2}, {4, 6}));
  const auto back = SegmentMoments::from_array(m.to_array());
  EXPECT_EQ(back.to_array(), m.to_array());
  EXPECT_EQ(SegmentMoments{}.rms_offset_m(), 0.0);
}

}  // namespace
}  // namespace wm::fusion
