#include "fusion/lines/scan_lines.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <random>
#include <utility>
#include <vector>

#include "fusion/kalman/line_map.h"

namespace wm::fusion {
namespace {

struct Wall {
  Eigen::Vector2d a, b;
};

// A room 8 m × 6 m with two boxes in it.
std::vector<Wall> room() {
  std::vector<Wall> walls = {{{0, 0}, {8, 0}}, {{8, 0}, {8, 6}}, {{8, 6}, {0, 6}}, {{0, 6}, {0, 0}}};
  auto box = [&](Eigen::Vector2d lo, Eigen::Vector2d hi) {
    walls.push_back({{lo.x(), lo.y()}, {hi.x(), lo.y()}});
    walls.push_back({{hi.x(), lo.y()}, {hi.x(), hi.y()}});
    walls.push_back({{hi.x(), hi.y()}, {lo.x(), hi.y()}});
    walls.push_back({{lo.x(), hi.y()}, {lo.x(), lo.y()}});
  };
  box({5.0, 1.5}, {6.2, 2.3});
  box({1.0, 4.0}, {1.8, 4.9});
  return walls;
}

// Distance along the ray from p in direction d to the nearest wall (nullopt: none).
std::optional<double> cast(const std::vector<Wall>& walls, const Eigen::Vector2d& p, const Eigen::Vector2d& d) {
  std::optional<double> best;
  for (const auto& w : walls) {
    const Eigen::Vector2d e = w.b - w.a;
    const double denom = d.x() * e.y() - d.y() * e.x();
    if (std::abs(denom) < 1e-12) continue;
    const Eigen::Vector2d ap = w.a - p;
    const double t = (ap.x() * e.y() - ap.y() * e.x()) / denom;
    const double u = (ap.x() * d.y() - ap.y() * d.x()) / denom;
    if (t > 1e-9 && u >= 0 && u <= 1 && (!best || t < *best)) best = t;
  }
  return best;
}

constexpr int kBeams = 1440;  // a full circle at 0.25°

// A full-circle scan with Gaussian range and bearing noise, as the extractor's model assumes.
std::vector<RangeReading> scan(const std::vector<Wall>& walls, const Pose2D& pose, const ScanLineOptions& o,
                               std::mt19937& rng, int beams = kBeams) {
  std::normal_distribution<double> range_noise(0.0, o.sigma_range_m), bearing_noise(0.0, o.sigma_bearing_rad);
  std::vector<RangeReading> readings;
  for (int i = 0; i < beams; ++i) {
    const double bearing = -std::numbers::pi + i * 2 * std::numbers::pi / beams;
    const double actual = pose.theta_rad + bearing + bearing_noise(rng);
    const auto r = cast(walls, {pose.x_m, pose.y_m}, {std::cos(actual), std::sin(actual)});
    if (r) readings.push_back({*r + range_noise(rng), bearing});
  }
  return readings;
}

LineFeature line_of(const Wall& w) { return LineSegment::from_points(w.a, w.b, Eigen::Matrix2d::Identity()).line; }

double angle_diff(double a, double b) { return std::remainder(a - b, 2 * std::numbers::pi); }

// |Δρ| and |Δφ| between two lines, over both representations ((ρ, φ) ≡ (−ρ, φ + π)).
std::pair<double, double> line_error(const LineFeature& a, const LineFeature& b) {
  const std::pair<double, double> same{std::abs(a.rho_m - b.rho_m), std::abs(angle_diff(a.phi_rad, b.phi_rad))};
  const std::pair<double, double> flipped{std::abs(a.rho_m + b.rho_m),
                                          std::abs(angle_diff(a.phi_rad + std::numbers::pi, b.phi_rad))};
  return same.first + same.second <= flipped.first + flipped.second ? same : flipped;
}

// Both endpoints of `s` within `tolerance` of wall w (its line and extent).
bool lies_on(const LineSegment& s, const Wall& w, double tolerance) {
  const Eigen::Vector2d e = (w.b - w.a).normalized();
  for (const Eigen::Vector2d& p : {s.p0(), s.p1()}) {
    const double t = (p - w.a).dot(e);
    if (t < -tolerance || t > (w.b - w.a).norm() + tolerance) return false;
    if (std::abs((p - w.a).x() * e.y() - (p - w.a).y() * e.x()) > tolerance) return false;
  }
  return true;
}

TEST(ScanLinesTest, FindsEveryVisibleWallAndNothingElse) {
  const auto walls = room();
  ScanLineOptions options;
  options.sigma_range_m = 0.005;  // a good indoor scanner
  std::mt19937 rng(42);
  for (const Pose2D pose : {Pose2D{3.0, 3.0, 0.2}, Pose2D{6.5, 4.5, -2.0}, Pose2D{2.0, 1.5, 1.0}}) {
    const auto readings = scan(walls, pose, options, rng);
    const auto segments = extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options);
    // The visible length of each wall: the noise-free readings that hit it.
    std::vector<double> visible(walls.size(), 0.0);
    std::vector<std::vector<Eigen::Vector2d>> hits(walls.size());
    for (int i = 0; i < kBeams; ++i) {
      const double a = pose.theta_rad - std::numbers::pi + i * 2 * std::numbers::pi / kBeams;
      const Eigen::Vector2d d(std::cos(a), std::sin(a));
      const auto r = cast(walls, {pose.x_m, pose.y_m}, d);
      if (!r) continue;
      const Eigen::Vector2d p = Eigen::Vector2d(pose.x_m, pose.y_m) + *r * d;
      for (std::size_t k = 0; k < walls.size(); ++k)
        if (std::abs(line_of(walls[k]).signed_distance(p)) < 1e-6) hits[k].push_back(p);
    }
    for (std::size_t k = 0; k < walls.size(); ++k) {
      if (hits[k].size() < 2) continue;
      double extent = 0;
      for (const auto& p : hits[k]) extent = std::max(extent, (p - hits[k].front()).norm());
      if (extent <= 0.5 || hits[k].size() < 12) continue;
      const LineFeature truth = line_of(walls[k]);
      bool found = false;
      for (const auto& s : segments) {
        const auto [d_rho, d_phi] = line_error(s.line, truth);
        if (d_rho < 0.02 && d_phi < 0.5 * std::numbers::pi / 180) found = true;
      }
      EXPECT_TRUE(found) << "wall " << k << " (" << extent << " m visible) from pose " << pose.x_m << "," << pose.y_m;
    }
    for (const auto& s : segments) {
      if (s.length_m() <= 0.3) continue;
      bool on_a_wall = false;
      for (const auto& w : walls) on_a_wall = on_a_wall || lies_on(s, w, 0.05);
      EXPECT_TRUE(on_a_wall) << "spurious segment " << s.p0().transpose() << " -> " << s.p1().transpose();
    }
  }
}

TEST(ScanLinesTest, CovarianceIsConsistentOverManyNoisyScans) {
  // Normalised estimation error squared of the far wall x = 8 over N scans: its mean must lie in the
  // two-sided 95 % band of χ²(2N)/N.
  const std::vector<Wall> walls = {{{8, -4}, {8, 4}}};
  ScanLineOptions options;
  options.sigma_range_m = 0.02;
  options.sigma_bearing_rad = 0.002;
  const Pose2D pose{3.0, 0.5, 0.3};
  const LineFeature truth = line_of(walls[0]);
  std::mt19937 rng(7);
  constexpr int kTrials = 300;
  double nees_sum = 0;
  int used = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    const auto segments = extract_scan_lines(scan(walls, pose, options, rng), pose, Eigen::Matrix3d::Zero(), options);
    // Occasionally (≈ 5 %, the merge test's level) a wall stays in two pieces; each is an estimate of it.
    ASSERT_FALSE(segments.empty()) << "trial " << trial;
    const auto longest = std::max_element(segments.begin(), segments.end(),
                                          [](const auto& a, const auto& b) { return a.length_m() < b.length_m(); });
    const auto& line = longest->line;
    const Eigen::Vector2d error(line.rho_m - truth.rho_m, angle_diff(line.phi_rad, truth.phi_rad));
    nees_sum += error.dot(line.cov.inverse() * error);
    ++used;
  }
  const double mean = nees_sum / used;
  // χ²(600) quantiles 2.5 % / 97.5 %: 533.1 and 670.7.
  EXPECT_GT(mean, 533.1 / kTrials);
  EXPECT_LT(mean, 670.7 / kTrials);
}

TEST(ScanLinesTest, PoseUncertaintyWidensTheWorldLine) {
  const auto walls = room();
  ScanLineOptions options;
  std::mt19937 rng(3);
  const Pose2D pose{3.0, 3.0, 0.2};
  const auto readings = scan(walls, pose, options, rng);
  const auto exact = extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options);
  const Eigen::Matrix3d pose_cov = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();
  const auto uncertain = extract_scan_lines(readings, pose, pose_cov, options);
  ASSERT_EQ(exact.size(), uncertain.size());
  for (std::size_t i = 0; i < exact.size(); ++i) {
    EXPECT_NEAR(exact[i].line.rho_m, uncertain[i].line.rho_m, 1e-12);
    EXPECT_GT(uncertain[i].line.cov(1, 1), exact[i].line.cov(1, 1) + 0.0009);
  }
}

TEST(ScanLinesTest, GapsSplitCollinearWallsAndShortPiecesAreDropped) {
  // Two collinear walls with a 1 m doorway, and a 0.2 m stub.
  const std::vector<Wall> walls = {{{-3, 2}, {-0.5, 2}}, {{0.5, 2}, {3, 2}}, {{2, -1}, {2.2, -1}}};
  ScanLineOptions options;
  std::mt19937 rng(5);
  const auto segments =
      extract_scan_lines(scan(walls, {0, 0, 0}, options, rng), {0, 0, 0}, Eigen::Matrix3d::Zero(), options);
  ASSERT_EQ(segments.size(), 2u);
  for (const auto& s : segments) EXPECT_NEAR(s.line.rho_m, 2.0, 0.01);
  EXPECT_GT(std::min(segments[0].length_m(), segments[1].length_m()), 2.0);
}

// A wall at y = 2 with a pilaster standing 13 cm out of it and a recess (a door frame) 13 cm deep: faces 13 cm apart
// that split-and-merge alone joined into short diagonals across the step and lines tilted toward the other face.
std::vector<Wall> stepped_wall() {
  return {{{-4, 2}, {-0.3, 2}},       {{-0.3, 2}, {-0.3, 1.87}}, {{-0.3, 1.87}, {0.3, 1.87}},
          {{0.3, 1.87}, {0.3, 2}},    {{0.3, 2}, {1.5, 2}},      {{1.5, 2}, {1.5, 2.13}},
          {{1.5, 2.13}, {2.4, 2.13}}, {{2.4, 2.13}, {2.4, 2}},   {{2.4, 2}, {4, 2}}};
}

TEST(ScanLinesTest, DepthStepsCutTheScanSoNoSegmentJoinsTwoFaces) {
  const auto walls = stepped_wall();
  ScanLineOptions options;
  options.sigma_range_m = 0.01;
  std::mt19937 rng(11);
  int segments_seen = 0;
  for (const int beams : {720, 1440}) {  // 0.5° and 0.25°
    for (const double x : {-3.8, -2.5, -1.2, -0.5, 0.0, 0.6, 1.2, 1.95, 3.0, 3.8}) {
      for (const double y : {1.7, 1.5, 1.2, 0.6, 0.0, -1.0}) {
        const Pose2D pose{x, y, 1.3};
        const auto segments =
            extract_scan_lines(scan(walls, pose, options, rng, beams), pose, Eigen::Matrix3d::Zero(), options);
        for (const auto& s : segments) {
          ++segments_seen;
          // Each segment on one face: both ends within 2 cm of its line, and within its extent up to 5 cm (the last
          // return before a corner is 2.4 σ of range noise along the wall when seen at 16°).
          bool on_one_face = false;
          for (const auto& w : walls) {
            const Eigen::Vector2d e = (w.b - w.a).normalized();
            bool on = true;
            for (const Eigen::Vector2d& p : {s.p0(), s.p1()}) {
              const double t = (p - w.a).dot(e);
              on = on && t > -0.05 && t < (w.b - w.a).norm() + 0.05 && std::abs(line_of(w).signed_distance(p)) < 0.02;
            }
            on_one_face = on_one_face || on;
          }
          EXPECT_TRUE(on_one_face) << beams << " beams, pose " << x << "," << y << ": " << s.length_m() << " m from "
                                   << s.p0().transpose() << " to " << s.p1().transpose();
        }
      }
    }
  }
  EXPECT_GT(segments_seen, 100);
}

// A door frame 7 cm proud of its wall, seen from the side of its step: the returns run on from the wall over the
// step's face to the frame with no jump, and a line through both faces can lie within the split's 4 cm of every
// return. Two parallel lines fit them far better: two segments, each on its face.
TEST(ScanLinesTest, AStepWithoutARangeJumpIsSplitIntoItsTwoFaces) {
  const std::vector<Wall> walls = {{{-0.8, 3}, {0, 3}}, {{0, 3}, {0, 2.93}}, {{0, 2.93}, {0.6, 2.93}}};
  const auto spanning = [&](bool split_steps) {
    ScanLineOptions options;
    options.split_steps = split_steps;
    std::mt19937 rng(5);
    int count = 0, segments = 0;
    for (const double x : {-4.0, -3.0, -2.5, -2.0, -1.5, -1.0, 1.0, 2.0, 3.0})
      for (const double y : {-3.0, -1.0, 0.0, 1.0, 2.0}) {
        const Pose2D pose{x, y, std::numbers::pi / 2};
        for (const auto& s :
             extract_scan_lines(scan(walls, pose, options, rng, 720), pose, Eigen::Matrix3d::Zero(), options)) {
          ++segments;
          count += lies_on(s, walls[0], 0.02) || lies_on(s, walls[2], 0.02) ? 0 : 1;
        }
      }
    EXPECT_GT(segments, 50);
    return count;
  };
  const int with_steps = spanning(true), without = spanning(false);
  EXPECT_LE(with_steps, 3);
  EXPECT_GT(without, with_steps) << "without the step test more segments should span both faces";
}

// A curved wall drawn as facets 6–9° apart (an office's rounded front): a line fitted to two facets tilts to split
// the difference, so no return lies 4 cm from it, and without the bend test the segment runs past the corner along
// the wrong facet. With it, each segment lies on one facet; a straight wall is split no more often than before.
TEST(ScanLinesTest, AShallowBendIsSplitIntoItsTwoFacets) {
  const auto facet = [](Eigen::Vector2d from, double degrees, double length) {
    const double a = degrees * std::numbers::pi / 180;
    return Wall{from, from + length * Eigen::Vector2d(std::cos(a), std::sin(a))};
  };
  std::vector<Wall> walls = {facet({-1.8, 3.0}, 0.0, 1.8)};
  walls.push_back(facet(walls.back().b, 8.0, 0.5));
  walls.push_back(facet(walls.back().b, 15.0, 0.6));
  // Along one facet: within 1.5° of its direction, both ends within 2 cm of its line and at most 12 cm past its
  // ends (where two facets 7° apart meet, the last returns of one lie within 1.5 cm of the other's line: no fit
  // places the corner closer than that).
  const auto along = [](const LineSegment& s, const Wall& w) {
    const Eigen::Vector2d e = (w.b - w.a).normalized(), d = (s.p1() - s.p0()).normalized();
    if (std::abs(e.x() * d.y() - e.y() * d.x()) > std::sin(1.5 * std::numbers::pi / 180)) return false;
    for (const Eigen::Vector2d& p : {s.p0(), s.p1()}) {
      const double t = (p - w.a).dot(e);
      if (t < -0.12 || t > (w.b - w.a).norm() + 0.12) return false;
      if (std::abs((p - w.a).x() * e.y() - (p - w.a).y() * e.x()) > 0.02) return false;
    }
    return true;
  };
  const auto spanning = [&](const std::vector<Wall>& drawn, bool split_bends) {
    ScanLineOptions options;
    options.split_bends = split_bends;
    std::mt19937 rng(8);
    int off = 0, segments = 0;
    // Driven past it 1–2 m away: from farther, at 0.5°, a 7° bend between two 0.5 m facets is within the noise.
    for (const double x : {-2.5, -2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0})
      for (const double y : {1.0, 1.5, 2.0}) {
        const Pose2D pose{x, y, std::numbers::pi / 2};
        for (const auto& s :
             extract_scan_lines(scan(drawn, pose, options, rng, 720), pose, Eigen::Matrix3d::Zero(), options)) {
          ++segments;
          off += std::any_of(drawn.begin(), drawn.end(), [&](const Wall& w) { return along(s, w); }) ? 0 : 1;
        }
      }
    EXPECT_GE(segments, 30);
    return std::pair{off, segments};
  };
  // 12 of 85 segments are off (a 0.5 m facet seen from 2 m at a slant: its bend is within 4σ); without the test, 34
  // of 61.
  const auto [with_bends, segments_with] = spanning(walls, true);
  const auto [without, segments_without] = spanning(walls, false);
  EXPECT_LT(with_bends, 0.2 * segments_with);
  EXPECT_GT(without, 0.45 * segments_without) << "without the bend test segments should span the corners";
  const std::vector<Wall> straight = {{{-2.0, 3.0}, {2.5, 3.0}}};
  EXPECT_EQ(spanning(straight, true), spanning(straight, false));
}

TEST(ScanLinesTest, TheBreakpointDetectorIsAnOption) {
  // Without it a 13 cm step seen head-on at 3 m is no gap of 0.25 m: the run spans both faces.
  const std::vector<Wall> walls = {{{-3, 3}, {0, 3}}, {{0, 3}, {0, 3.13}}, {{0, 3.13}, {3, 3.13}}};
  ScanLineOptions options;
  std::mt19937 rng(2);
  const auto readings = scan(walls, {0.8, 0, std::numbers::pi / 2}, options, rng, 720);
  for (const bool adaptive : {true, false}) {
    options.adaptive_breakpoints = adaptive;
    const auto segments =
        extract_scan_lines(readings, {0.8, 0, std::numbers::pi / 2}, Eigen::Matrix3d::Zero(), options);
    ASSERT_EQ(segments.size(), 2u) << adaptive;
    for (const auto& s : segments) {
      const double rho = std::abs(s.line.rho_m);
      EXPECT_TRUE(std::abs(rho - 3.0) < 0.01 || std::abs(rho - 3.13) < 0.01) << rho;
    }
  }
  options.breakpoint_lambda_rad = 0;
  EXPECT_THROW(extract_scan_lines(readings, {0, 0, 0}, Eigen::Matrix3d::Zero(), options), std::invalid_argument);
}

TEST(ScanLinesTest, AFarWallWhoseReturnsLieFartherApartThanTheGapIsStillOneSegment) {
  // A 5 m wall 15–19 m away seen at 25–33° by a 0.5° laser: its returns lie 0.24–0.39 m apart, more than max_gap_m.
  // A doorway of 0.9 m in a wall 3 m away is wider than any such spacing and still cuts.
  const std::vector<Wall> walls = {{{12.5, 5}, {17.5, 5}}, {{-4, 3}, {-1.6, 3}}, {{-0.7, 3}, {2, 3}}};
  ScanLineOptions options;
  std::mt19937 rng(4);
  const Pose2D pose{0, -3, 0};
  const auto readings = scan(walls, pose, options, rng, 720);
  const auto segments = extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options);
  std::size_t far = 0, near = 0;
  for (const auto& s : segments) {
    if (lies_on(s, walls[0], 0.05)) {
      ++far;
      EXPECT_GT(s.length_m(), 4.0);
    }
    if (lies_on(s, walls[1], 0.03) || lies_on(s, walls[2], 0.03)) ++near;
  }
  EXPECT_EQ(far, 1u);
  EXPECT_EQ(near, 2u);  // the doorway cut the near wall in two
  EXPECT_EQ(segments.size(), 3u);

  // max_gap_m alone, or the far wall beyond the range where far gaps join: it falls apart into points.
  for (const auto& [lambda, max_range] : {std::pair{0.0, 20.0}, std::pair{0.2618, 10.0}}) {
    options.far_gap_lambda_rad = lambda;
    options.far_gap_max_range_m = max_range;
    std::size_t far_without = 0;
    for (const auto& s : extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options))
      far_without += lies_on(s, walls[0], 0.05) ? 1 : 0;
    EXPECT_EQ(far_without, 0u) << lambda << " " << max_range;
  }
  options.far_gap_lambda_rad = std::numbers::pi / 2;
  EXPECT_THROW(extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options), std::invalid_argument);
}

TEST(ScanLinesTest, AFarGapIsNeverWiderThanADoorway) {
  // A wall 17 m ahead with a 0.9 m doorway, seen head on by a 1° laser whose step is not known: its returns lie
  // 0.3 m apart, and the beams through the doorway return nothing. The 1.2 m between the returns either side of the
  // doorway is within the far-gap spacing of a surface seen at 15° from 4° apart. Here the jump also stands out
  // among its neighbours' spacings, a breakpoint; seen obliquely the spacings beside an opening are wide too, so the
  // breakpoints are set aside and only the gap's own width may keep the doorway open.
  const std::vector<Wall> walls = {{{-3, 17}, {-0.45, 17}}, {{0.45, 17}, {3, 17}}};
  ScanLineOptions options;
  options.breakpoint_isolation = 100;  // no jump stands out so far
  std::mt19937 rng(6);
  const Pose2D pose{0, 0, 0};
  const auto readings = scan(walls, pose, options, rng, 360);
  const auto segments = extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options);
  ASSERT_EQ(segments.size(), 2u);
  for (const auto& s : segments) EXPECT_TRUE(lies_on(s, walls[0], 0.05) || lies_on(s, walls[1], 0.05));

  options.far_gap_max_m = 2.0;  // wider than the doorway: one line across it
  const auto across = extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options);
  ASSERT_EQ(across.size(), 1u);
  EXPECT_GT(across.front().length_m(), 5.0);
  options.far_gap_max_m = -1;
  EXPECT_THROW(extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options), std::invalid_argument);
}

TEST(ScanLinesTest, AnOpeningSeenThroughManyEmptyBeamsCutsWhenTheBeamStepIsKnown) {
  // Seen from 14 m: a wall ends at y = 11.93, the beams past its end return nothing up to a far wall at y = 14.19
  // seen at 8°, whose first return lies on the first wall's line. The 2.3 m between the two returns is within the
  // far-gap spacing of a surface seen at 15° from 9° apart, and no breakpoint (the far wall's own returns lie
  // 0.8 m apart), so without the beam step, and with far gaps as wide as 3 m, one line runs along the first wall
  // and across the opening. Either the beam step or the far gaps' own limit (0.75 m) keeps it open.
  constexpr int kHalfDegreeBeams = 720;
  const double step = 2 * std::numbers::pi / kHalfDegreeBeams;
  const Pose2D pose{21.14, 12.27, std::numbers::pi / 2};  // the scan's first beam points away from the scene
  double end_x = 0, best = 1e9;                           // where the beam nearest to x = 7.55 meets y = 14.19
  for (int i = 0; i < kHalfDegreeBeams; ++i) {
    const double bearing = pose.theta_rad - std::numbers::pi + i * step;
    if (std::sin(bearing) <= 0.01) continue;
    const double x = pose.x_m + (14.19 - pose.y_m) * std::cos(bearing) / std::sin(bearing);
    if (std::abs(x - 7.55) < best) best = std::abs(x - 7.55), end_x = x;
  }
  const std::vector<Wall> walls = {{{end_x, 8.0}, {end_x, 11.93}}, {{end_x - 0.01, 14.19}, {25, 14.19}}};
  ScanLineOptions options;
  options.sigma_bearing_rad = 0;
  std::mt19937 rng(7);
  const auto readings = scan(walls, pose, options, rng, kHalfDegreeBeams);
  const auto across = [&](const ScanLineOptions& o) {
    std::size_t n = 0;
    for (const auto& s : extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), o))
      n += std::abs(s.p0().x() - end_x) < 0.05 && std::abs(s.p1().x() - end_x) < 0.05 &&
                   std::max(s.p0().y(), s.p1().y()) > 12.5
               ? 1
               : 0;
    return n;
  };
  EXPECT_EQ(across(options), 0u) << "2.3 m is wider than any far gap";
  options.far_gap_max_m = 3.0;
  EXPECT_EQ(across(options), 1u) << "the test no longer shows the opening joined without the beam step";
  options.bearing_step_rad = step;
  EXPECT_EQ(across(options), 0u);
  std::size_t on_wall = 0;
  for (const auto& s : extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options))
    on_wall += lies_on(s, walls[0], 0.03) ? 1 : 0;
  EXPECT_EQ(on_wall, 1u) << "the wall itself is still seen";
  options.bearing_step_rad = -0.01;
  EXPECT_THROW(extract_scan_lines(readings, pose, Eigen::Matrix3d::Zero(), options), std::invalid_argument);
}

TEST(ScanLinesTest, BadInputIsRefused) {
  ScanLineOptions options;
  EXPECT_THROW(extract_scan_lines({{std::nan(""), 0.0}}, {0, 0, 0}, Eigen::Matrix3d::Zero(), options),
               std::invalid_argument);
  EXPECT_THROW(extract_scan_lines({}, {std::nan(""), 0, 0}, Eigen::Matrix3d::Zero(), options), std::invalid_argument);
  options.min_points = 1;
  EXPECT_THROW(extract_scan_lines({}, {0, 0, 0}, Eigen::Matrix3d::Zero(), options), std::invalid_argument);
  EXPECT_TRUE(extract_scan_lines({}, {0, 0, 0}, Eigen::Matrix3d::Zero(), ScanLineOptions{}).empty());
}

}  // namespace
}  // namespace wm::fusion
