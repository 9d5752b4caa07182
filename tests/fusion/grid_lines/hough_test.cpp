#include "fusion/grid_lines/hough.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include "tests/fusion/grid_lines/synthetic_raster.h"

namespace wm::fusion {
namespace {

constexpr double kDeg = std::numbers::pi / 180;
constexpr double kRes = 0.05;

// A free 200 × 160 raster at 5 cm with its origin at (−3, 2) m, and an empty image over it.
struct Canvas {
  ProbabilityRaster raster{GridGeometry({-3.0, 2.0}, kRes, 200, 160), std::vector<float>(200 * 160, 0.2f)};
  std::vector<std::uint8_t> image = std::vector<std::uint8_t>(200 * 160, 0);

  // Marks the cells a 1-cell line from a to b [m] passes through (their centres within half a cell), with p.
  void line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, float p) {
    const int steps = static_cast<int>((b - a).norm() / (0.25 * kRes));
    for (int i = 0; i <= steps; ++i) {
      const CellIndex c = raster.geometry.cell_of(a + (b - a) * i / steps);
      const auto k = static_cast<std::size_t>(c.y * 200 + c.x);
      image[k] = 1;
      raster.p[k] = p;
    }
  }
};

TEST(HoughTest, FindsASingleLineWithinHalfABin) {
  Canvas canvas;
  const testing::TrueWall wall{{-2.0, 3.0}, {5.0, 8.0}};
  canvas.line(wall.a, wall.b, 0.9f);
  const std::vector<HoughPeak> peaks = hough_peaks(canvas.raster, canvas.image, HoughOptions{});
  ASSERT_FALSE(peaks.empty());
  const auto diff = testing::difference(wall.line(), LineFeature{peaks[0].rho_m, peaks[0].phi_rad, {}});
  EXPECT_LT(diff.phi_rad, 0.5 * kDeg + 1e-9);
  EXPECT_LT(diff.rho_m, kRes);  // half a ρ bin plus the cells' own staircase
  // A 1° bin over an 8.6 m line: the cells drift up to 1.3 cells across the bin's centre line at the ends, so about
  // three quarters of them vote in the peak's ρ bin.
  EXPECT_GE(peaks[0].votes, 0.7 * (wall.b - wall.a).norm() / kRes);
  // Nothing else in the image comes near it (the neighbours outside the suppression window hold the staircase's
  // leftovers).
  for (std::size_t i = 1; i < peaks.size(); ++i) EXPECT_LT(peaks[i].votes, 0.3 * peaks[0].votes);
}

TEST(HoughTest, NonMaximumSuppressionCollapsesADoubledWall) {
  // Both faces of a 10 cm wall, 2 cells apart (on cell centres, so each face is one row): one line with the
  // default window, two without suppression.
  Canvas canvas;
  canvas.line({-2.0, 4.025}, {6.0, 4.025}, 0.9f);
  canvas.line({-2.0, 4.125}, {6.0, 4.125}, 0.9f);
  const std::vector<HoughPeak> collapsed = hough_peaks(canvas.raster, canvas.image, HoughOptions{});
  std::size_t strong = 0;
  for (const HoughPeak& p : collapsed) strong += p.votes >= 0.5 * collapsed[0].votes ? 1 : 0;
  EXPECT_EQ(strong, 1u);
  EXPECT_NEAR(std::abs(std::sin(collapsed[0].phi_rad)), 1.0, 1e-9);
  EXPECT_NEAR(collapsed[0].rho_m * std::sin(collapsed[0].phi_rad), 4.075, 0.051);

  HoughOptions no_nms;
  no_nms.nms_rho_m = 0.0;
  no_nms.nms_theta_rad = 0.0;
  const std::vector<HoughPeak> separate = hough_peaks(canvas.raster, canvas.image, no_nms);
  ASSERT_GE(separate.size(), 2u);
  EXPECT_GE(separate[1].votes, 0.9 * separate[0].votes);
  EXPECT_NEAR(std::abs(separate[0].rho_m - separate[1].rho_m), 0.1, 1e-9);
}

TEST(HoughTest, SuppressionWrapsAcrossPhiZeroAndPi) {
  // Two near-vertical lines at normal angles +0.7° and −0.7° (bins next to 0 and next to π): one wall.
  Canvas canvas;
  const Eigen::Vector2d mid(2.0, 6.0);
  for (const double tilt : {0.7 * kDeg, -0.7 * kDeg}) {
    const Eigen::Vector2d d(-std::sin(tilt), std::cos(tilt));
    canvas.line(mid - 3.0 * d, mid + 3.0 * d, 0.9f);
  }
  const std::vector<HoughPeak> peaks = hough_peaks(canvas.raster, canvas.image, HoughOptions{});
  ASSERT_FALSE(peaks.empty());
  std::size_t strong = 0;
  for (const HoughPeak& p : peaks) strong += p.votes >= 0.5 * peaks[0].votes ? 1 : 0;
  EXPECT_EQ(strong, 1u);
  EXPECT_NEAR(std::abs(std::cos(peaks[0].phi_rad)), 1.0, 1e-3);
}

// Two parallel skeleton lines 2 cells apart with the same votes; the raster holds one as a strong, thick wall
// and the other as a weak one. `strong_first`: the strong line is the lower one.
Canvas tie(bool strong_first) {
  Canvas canvas;
  const double y_strong = strong_first ? 4.0 : 4.1;
  const double y_weak = strong_first ? 4.1 : 4.0;
  canvas.line({-2.0, y_strong}, {6.0, y_strong}, 0.95f);
  canvas.line({-2.0, y_weak}, {6.0, y_weak}, 0.6f);
  return canvas;
}

TEST(HoughTest, AmbiguousPeaksAreSettledOnTheGreyGrid) {
  for (const bool strong_first : {true, false}) {
    SCOPED_TRACE(strong_first);
    const Canvas canvas = tie(strong_first);
    const std::vector<HoughPeak> peaks = hough_peaks(canvas.raster, canvas.image, HoughOptions{});
    ASSERT_FALSE(peaks.empty());
    EXPECT_TRUE(peaks[0].grey_resolved);
    EXPECT_NEAR(std::abs(std::sin(peaks[0].phi_rad)), 1.0, 1e-9);
    // The strong line's cell centres are at y = 4.025 (first) or 4.125 m (second).
    EXPECT_NEAR(std::abs(peaks[0].rho_m * std::sin(peaks[0].phi_rad)), strong_first ? 4.025 : 4.125, 0.026);
  }
}

TEST(HoughTest, WithoutTheGreyFallbackATieIsBrokenByBinOrderAlone) {
  // The same ties with the fallback off: the same bin wins both times, so one of the two picks the weak line.
  HoughOptions off;
  off.ambiguous_ratio = 2.0;
  double picked[2];
  for (const bool strong_first : {true, false}) {
    const Canvas canvas = tie(strong_first);
    const std::vector<HoughPeak> peaks = hough_peaks(canvas.raster, canvas.image, off);
    ASSERT_FALSE(peaks.empty());
    EXPECT_FALSE(peaks[0].grey_resolved);
    picked[strong_first ? 0 : 1] = std::abs(peaks[0].rho_m * std::sin(peaks[0].phi_rad));
  }
  EXPECT_NEAR(picked[0], picked[1], 1e-9);
}

TEST(HoughTest, OccupancyWeightingVotesWithTheCellsProbability) {
  Canvas canvas;
  canvas.line({-2.0, 4.0}, {6.0, 4.0}, 0.8f);  // 160 cells
  const std::vector<HoughPeak> binary = hough_peaks(canvas.raster, canvas.image, HoughOptions{});
  const std::vector<HoughPeak> grey =
      hough_peaks(canvas.raster, canvas.image, HoughOptions{}, HoughWeighting::occupancy);
  ASSERT_FALSE(binary.empty());
  ASSERT_FALSE(grey.empty());
  EXPECT_NEAR(grey[0].votes, 0.8 * binary[0].votes, 1e-3);
  EXPECT_NEAR(binary[0].votes, 161.0, 1.0);
}

TEST(HoughTest, RejectsBadOptionsAndMismatchedImages) {
  Canvas canvas;
  HoughOptions bad;
  bad.rho_step_cells = 0.0;
  EXPECT_THROW(hough_peaks(canvas.raster, canvas.image, bad), std::invalid_argument);
  bad = {};
  bad.min_votes = 0.0;
  EXPECT_THROW(validate(bad), std::invalid_argument);
  bad = {};
  bad.theta_step_rad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(validate(bad), std::invalid_argument);
  bad = {};
  bad.ambiguous_ratio = -1.0;
  EXPECT_THROW(validate(bad), std::invalid_argument);
  const std::vector<std::uint8_t> wrong(10, 1);
  EXPECT_THROW(hough_peaks(canvas.raster, wrong, HoughOptions{}), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
