#include "fusion/geometry/angle.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

namespace wm::fusion {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(NormalizeAngleTest, LeavesAnglesInsideTheIntervalUnchanged) {
  EXPECT_EQ(normalize_angle(0.0), 0.0);
  EXPECT_EQ(normalize_angle(0.1), 0.1);
  EXPECT_EQ(normalize_angle(-0.1), -0.1);
  EXPECT_EQ(normalize_angle(3.0), 3.0);
  EXPECT_EQ(normalize_angle(-3.0), -3.0);
}

TEST(NormalizeAngleTest, MapsBothEndsOfThePiCircleToPlusPi) {
  EXPECT_EQ(normalize_angle(kPi), kPi);
  EXPECT_EQ(normalize_angle(-kPi), kPi);
}

TEST(NormalizeAngleTest, WrapsMultiplesOfTwoPi) {
  EXPECT_NEAR(normalize_angle(2.0 * kPi + 0.1), 0.1, 1e-15);
  EXPECT_NEAR(normalize_angle(-2.0 * kPi - 0.1), -0.1, 1e-15);
  EXPECT_NEAR(normalize_angle(1.5 * kPi), -0.5 * kPi, 1e-15);
  EXPECT_NEAR(normalize_angle(-1.5 * kPi), 0.5 * kPi, 1e-15);
  EXPECT_NEAR(normalize_angle(3.0 * kPi), kPi, 1e-14);
}

TEST(NormalizeAngleTest, KeepsTheDirectionOfLargeAngles) {
  for (double a : {1000.0, -1000.0, 12345.678}) {
    const double w = normalize_angle(a);
    EXPECT_GT(w, -kPi);
    EXPECT_LE(w, kPi);
    EXPECT_NEAR(std::cos(w), std::cos(a), 1e-12);
    EXPECT_NEAR(std::sin(w), std::sin(a), 1e-12);
  }
}

TEST(NormalizeAngleTest, PassesNanThrough) {
  EXPECT_TRUE(std::isnan(normalize_angle(std::numeric_limits<double>::quiet_NaN())));
}

}  // namespace
}  // namespace wm::fusion
