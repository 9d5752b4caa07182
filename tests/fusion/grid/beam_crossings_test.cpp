#include "fusion/grid/beam_crossings.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>

namespace wm::fusion {
namespace {

// A 360° scan of 720 beams at (0, 0), every beam returning at `range` unless `range_of` says otherwise.
LaserScan ring_scan(double range) {
  LaserScan scan;
  scan.sensor_pose = {0, 0, 0};
  scan.angle_min_rad = -std::numbers::pi;
  scan.angle_increment_rad = 2 * std::numbers::pi / 720;
  scan.ranges_m.assign(720, range);
  scan.range_min_m = 0.05;
  scan.range_max_m = 30;
  return scan;
}

SegmentBeams segment(Eigen::Vector2d p0, Eigen::Vector2d p1, const BeamCrossingOptions& options) {
  SegmentBeams s{p0, p1, {}, {}};
  s.through.assign(beam_bins((p1 - p0).norm(), options), 0);
  s.ended.assign(s.through.size(), 0);
  return s;
}

std::uint32_t total(const std::vector<std::uint32_t>& bins) { return std::accumulate(bins.begin(), bins.end(), 0u); }

TEST(BeamCrossingsTest, BeamsReturningBeyondASegmentPassThroughIt) {
  const BeamCrossingOptions options;
  // A 2 m segment 2 m in front of the sensor (x = 2, y from −1 to 1), walls at 5 m: it subtends 2·atan(0.5) = 53.1°,
  // so 106 beams of 0.5° cross it.
  std::vector<SegmentBeams> segments{segment({2, -1}, {2, 1}, options)};
  count_beam_crossings(ring_scan(5.0), 20.0, options, segments);
  EXPECT_EQ(total(segments[0].ended), 0u);
  EXPECT_NEAR(total(segments[0].through), 106.0, 1.0);
  EXPECT_EQ(segments[0].through.size(), 20u);
  // More beams cross the middle of the segment than its ends (closer, seen at a wider angle).
  EXPECT_GT(segments[0].through[10], segments[0].through[0]);
}

TEST(BeamCrossingsTest, BeamsReturningOnASegmentEndOnIt) {
  const BeamCrossingOptions options;
  std::vector<SegmentBeams> segments{segment({2, -1}, {2, 1}, options)};
  auto scan = ring_scan(5.0);
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double bearing = scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
    if (std::abs(bearing) < std::atan(0.5)) scan.ranges_m[i] = 2.0 / std::cos(bearing) + 0.02;  // the wall stands
  }
  count_beam_crossings(scan, 20.0, options, segments);
  EXPECT_NEAR(total(segments[0].ended), 106.0, 1.0);
  EXPECT_EQ(total(segments[0].through), 0u);
}

TEST(BeamCrossingsTest, ShortReturnsBeforeTheSegmentAndOutOfReachCountNothing) {
  const BeamCrossingOptions options;
  std::vector<SegmentBeams> segments{segment({2, -1}, {2, 1}, options), segment({40, -1}, {40, 1}, options)};
  count_beam_crossings(ring_scan(1.0), 20.0, options, segments);  // a person right in front: nothing behind is seen
  for (const auto& s : segments) EXPECT_EQ(total(s.through) + total(s.ended), 0u);
  count_beam_crossings(ring_scan(50.0), 20.0, options, segments);  // returns beyond reach: free up to 20 m only
  EXPECT_GT(total(segments[0].through), 0u);
  EXPECT_EQ(total(segments[1].through), 0u);
}

TEST(BeamCrossingsTest, NoReturnClearsUpToTheRangeMax) {
  const BeamCrossingOptions options;
  std::vector<SegmentBeams> segments{segment({2, -1}, {2, 1}, options)};
  auto scan = ring_scan(std::numeric_limits<double>::infinity());
  count_beam_crossings(scan, 20.0, options, segments);
  EXPECT_NEAR(total(segments[0].through), 106.0, 1.0);
  scan.ranges_m.assign(scan.ranges_m.size(), std::nan(""));  // no readings at all
  segments = {segment({2, -1}, {2, 1}, options)};
  count_beam_crossings(scan, 20.0, options, segments);
  EXPECT_EQ(total(segments[0].through), 0u);
}

TEST(BeamCrossingsTest, GrazingBeamsAreNotCounted) {
  BeamCrossingOptions options;
  // A segment nearly along the beams that reach it: from (1, 0.1) to (6, 0.9), 0.5° to 3.4° off them.
  std::vector<SegmentBeams> segments{segment({1, 0.1}, {6, 0.9}, options)};
  count_beam_crossings(ring_scan(10.0), 20.0, options, segments);
  EXPECT_EQ(total(segments[0].through), 0u);
  options.min_incidence_rad = 0;
  segments = {segment({1, 0.1}, {6, 0.9}, options)};
  count_beam_crossings(ring_scan(10.0), 20.0, options, segments);
  EXPECT_GE(total(segments[0].through), 4u);
}

// Every beam that crosses `wall` returns `beyond_m` past it along the beam.
LaserScan returning_past(const SegmentBeams& wall, double beyond_m) {
  auto scan = ring_scan(30.0);
  const Eigen::Vector2d along = wall.p1 - wall.p0;
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double bearing = scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
    const Eigen::Vector2d dir(std::cos(bearing), std::sin(bearing));
    const double denom = dir.x() * along.y() - dir.y() * along.x();
    if (std::abs(denom) < 1e-12) continue;
    const double t = (wall.p0.x() * along.y() - wall.p0.y() * along.x()) / denom;
    const double u = (wall.p0.x() * dir.y() - wall.p0.y() * dir.x()) / denom;
    if (t > 0 && u >= 0 && u <= 1) scan.ranges_m[i] = t + beyond_m;
  }
  return scan;
}

TEST(BeamCrossingsTest, TheMarginIsMeasuredAcrossTheSegment) {
  const BeamCrossingOptions options;
  // A wall the beams meet at 16°–22°: a return 0.25 m past it along the beam is 7–9 cm behind its line, within
  // the 10 cm margin (noise of a wall that stands); 1 m past it is 28–37 cm behind (the beam went through).
  const auto wall = segment({2, 5}, {2, 7}, options);
  std::vector<SegmentBeams> segments{wall};
  count_beam_crossings(returning_past(wall, 0.25), 20.0, options, segments);
  EXPECT_GT(total(segments[0].ended), 5u);
  EXPECT_EQ(total(segments[0].through), 0u);
  segments = {wall};
  count_beam_crossings(returning_past(wall, 1.0), 20.0, options, segments);
  EXPECT_EQ(total(segments[0].ended), 0u);
  EXPECT_GT(total(segments[0].through), 5u);
}

TEST(BeamCrossingsTest, AnUncertainPoseWidensTheMargin) {
  const BeamCrossingOptions options;
  // Returns 0.6 m past the wall along the beam, 17–22 cm behind it: through for a pose known exactly; with a heading
  // σ of 1° the return 6 m away is ±10 cm across the wall at one σ, so they are not counted as passing.
  const auto wall = segment({2, 5}, {2, 7}, options);
  const auto scan = returning_past(wall, 0.6);
  std::vector<SegmentBeams> segments{wall};
  count_beam_crossings(scan, 20.0, options, segments);
  EXPECT_GT(total(segments[0].through), 5u);
  Eigen::Matrix3d pose_cov = Eigen::Matrix3d::Zero();
  pose_cov(2, 2) = std::pow(std::numbers::pi / 180, 2);
  segments = {wall};
  count_beam_crossings(scan, 20.0, options, segments, pose_cov);
  EXPECT_EQ(total(segments[0].through), 0u);
  EXPECT_GT(total(segments[0].ended), 5u);
  pose_cov(0, 0) = std::nan("");
  EXPECT_THROW(count_beam_crossings(scan, 20.0, options, segments, pose_cov), std::invalid_argument);
}

TEST(BeamCrossingsTest, SegmentBehindTheScanStartIsFoundAcrossTheWrap) {
  const BeamCrossingOptions options;
  // Straight behind the sensor, where a scan starting at −π wraps.
  std::vector<SegmentBeams> segments{segment({-2, 1}, {-2, -1}, options)};
  count_beam_crossings(ring_scan(5.0), 20.0, options, segments);
  EXPECT_NEAR(total(segments[0].through), 106.0, 2.0);
}

TEST(BeamCrossingsTest, BadInputIsRefused) {
  BeamCrossingOptions options;
  std::vector<SegmentBeams> segments{segment({2, -1}, {2, 1}, options)};
  segments[0].through.resize(3);
  EXPECT_THROW(count_beam_crossings(ring_scan(5.0), 20.0, options, segments), std::invalid_argument);
  segments = {segment({2, -1}, {2, 1}, options)};
  EXPECT_THROW(count_beam_crossings(ring_scan(5.0), std::nan(""), options, segments), std::invalid_argument);
  auto no_angle = ring_scan(5.0);
  no_angle.angle_increment_rad = std::nan("");
  EXPECT_THROW(count_beam_crossings(no_angle, 20.0, options, segments), std::invalid_argument);
  options.bin_m = 0;
  EXPECT_THROW(count_beam_crossings(ring_scan(5.0), 20.0, options, segments), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
