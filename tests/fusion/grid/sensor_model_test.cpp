#include "fusion/grid/sensor_model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

namespace wm::fusion {
namespace {

constexpr double kRes = 0.05;
constexpr double kDeg = std::numbers::pi / 180.0;

double logit(double p) { return std::log(p / (1.0 - p)); }

// A single-beam laser scan; the sensor model options decide the beam width.
LaserScan one_beam(Pose2D pose, double reading, double range_max = 30.0) {
  LaserScan s;
  s.sensor_pose = pose;
  s.ranges_m = {reading};
  s.range_min_m = 0.02;
  s.range_max_m = range_max;
  s.sigma_range_m = 0.01;
  return s;
}

SensorModelOptions thin() {
  SensorModelOptions o;
  o.laser_beam_width_rad = 0.0;
  return o;
}

std::vector<BeamCell> cells_of(const LaserScan& scan, const SensorModelOptions& o) {
  const std::optional<Beam> beam = laser_beam(scan, 0, o);
  if (!beam) return {};
  return beam_cells(*beam, kRes);
}

std::set<std::pair<std::int64_t, std::int64_t>> keys(const std::vector<BeamCell>& cells, bool hit) {
  std::set<std::pair<std::int64_t, std::int64_t>> out;
  for (const BeamCell& c : cells) {
    if (c.hit == hit) out.insert({c.cell.x, c.cell.y});
  }
  return out;
}

TEST(SensorModelTest, ValidateRejectsOutOfRangeOptions) {
  EXPECT_NO_THROW(validate(SensorModelOptions{}));
  auto bad = [](auto mutate) {
    SensorModelOptions o;
    mutate(o);
    return o;
  };
  EXPECT_THROW(validate(bad([](auto& o) { o.p_hit = 0.5; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.p_miss = 0.5; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.sonar_p_hit = 1.0; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.sonar_p_miss = 0.0; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.ds_empty_factor_k = 1.0; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.ds_laser_occupied_mass = 1.0; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.ds_sonar_occupied_mass = 0.0; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.laser_beam_width_rad = 2.0; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.sonar_sigma_per_range = -0.1; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.max_usable_range_m = 0.0; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([](auto& o) { o.max_usable_range_m = std::numeric_limits<double>::infinity(); })),
               std::invalid_argument);
}

// Sensor at the centre of cell (0, 0), beam along +x, return at 1.01 m: in the cell x = 20 (1.00–1.05 m).
TEST(SensorModelTest, ThinBeamAlongXFreesTheCellsBeforeTheReturnAndHitsItsCell) {
  const auto cells = cells_of(one_beam({0.025, 0.025, 0.0}, 1.01), thin());
  std::set<std::pair<std::int64_t, std::int64_t>> expected_free;
  for (std::int64_t x = 0; x < 20; ++x) expected_free.insert({x, 0});
  EXPECT_EQ(keys(cells, false), expected_free);
  EXPECT_EQ(keys(cells, true), (std::set<std::pair<std::int64_t, std::int64_t>>{{20, 0}}));
  ASSERT_EQ(cells.size(), 21u);
  EXPECT_EQ(cells.front().cell, (CellIndex{0, 0}));  // outward from the sensor

  // Bayes: p_miss on free cells, p_hit at the return cell (g = 1 there).
  for (const BeamCell& c : cells) EXPECT_NEAR(c.bayes_log_odds, c.hit ? logit(0.7) : logit(0.4), 1e-12);

  // DS, eq. (1), by hand: σ_e² = σ² + (cell/2)² in cells = 0.2² + 0.5² = 0.29.
  const BeamCell& hit = cells.back();
  EXPECT_NEAR(hit.distance_m, 1.0, 1e-12);
  EXPECT_NEAR(hit.m_occupied, 0.9, 1e-12);
  EXPECT_NEAR(hit.m_empty, 0.9 * (1.0 - 0.9), 1e-12);  // centre (1.00 m) in front of the reading
  const BeamCell& before = cells[19];                  // centre 0.95 m: 1.2 cells in front of the reading
  const double g = std::exp(-1.2 * 1.2 / (2.0 * 0.29));
  EXPECT_NEAR(before.m_occupied, 0.9 * g, 1e-9);
  EXPECT_NEAR(before.m_empty, 0.9 * (1.0 - 0.9 * g), 1e-9);
  EXPECT_DOUBLE_EQ(cells[5].m_occupied, 0.0);  // far in front: no occupied mass
  EXPECT_DOUBLE_EQ(cells[5].m_empty, 0.9);
}

TEST(SensorModelTest, BeamAlongNegativeYWalksDownwards) {
  const auto cells = cells_of(one_beam({0.025, 0.025, -std::numbers::pi / 2}, 0.51), thin());
  std::set<std::pair<std::int64_t, std::int64_t>> expected_free;
  for (std::int64_t y = 0; y > -10; --y) expected_free.insert({0, y});
  EXPECT_EQ(keys(cells, false), expected_free);
  EXPECT_EQ(keys(cells, true), (std::set<std::pair<std::int64_t, std::int64_t>>{{0, -10}}));
}

TEST(SensorModelTest, MaxRangeReadingClearsWithoutMarking) {
  // range_max 0.99 m: cells whose centres lie within 0.99 m are free, none is hit.
  const auto cells = cells_of(one_beam({0.025, 0.025, 0.0}, 5.0, 0.99), thin());
  std::set<std::pair<std::int64_t, std::int64_t>> expected_free;
  for (std::int64_t x = 0; x < 20; ++x) expected_free.insert({x, 0});
  EXPECT_EQ(keys(cells, false), expected_free);
  EXPECT_TRUE(keys(cells, true).empty());
  for (const BeamCell& c : cells) {
    EXPECT_DOUBLE_EQ(c.m_occupied, 0.0);
    EXPECT_DOUBLE_EQ(c.m_empty, 0.9);
  }
  // +inf is "no return" too (ROS convention).
  const auto inf = cells_of(one_beam({0.025, 0.025, 0.0}, std::numeric_limits<double>::infinity(), 0.99), thin());
  EXPECT_EQ(keys(inf, false), expected_free);
}

TEST(SensorModelTest, ReadingBeyondUsableRangeClearsUpToIt) {
  SensorModelOptions o = thin();
  o.max_usable_range_m = 0.5;
  const std::optional<Beam> beam = laser_beam(one_beam({0.025, 0.025, 0.0}, 3.0), 0, o);
  ASSERT_TRUE(beam);
  EXPECT_FALSE(beam->has_return);
  EXPECT_DOUBLE_EQ(beam->range_m, 0.5);
  const auto cells = beam_cells(*beam, kRes);
  EXPECT_TRUE(keys(cells, true).empty());
  EXPECT_EQ(keys(cells, false).size(), 11u);  // centres at 0 … 0.5 m
}

TEST(SensorModelTest, AScansOwnUsableRangeAndRangeDependentSigmaWin) {
  SensorModelOptions o = thin();
  o.max_usable_range_m = 0.5;
  LaserScan s = one_beam({0.025, 0.025, 0.0}, 3.0);
  s.usable_range_m = 4.0;  // this sensor is good far out: its 3 m return marks a cell
  s.sigma_range_m = 0.01;
  s.sigma_range_per_m = 0.005;
  const std::optional<Beam> beam = laser_beam(s, 0, o);
  ASSERT_TRUE(beam);
  EXPECT_TRUE(beam->has_return);
  EXPECT_DOUBLE_EQ(beam->range_m, 3.0);
  EXPECT_DOUBLE_EQ(beam->sigma_m, 0.01 + 0.005 * 3.0);
  EXPECT_DOUBLE_EQ(usable_range_m(s, o), 4.0);
  s.usable_range_m = 0.0;  // not given: the grid's
  EXPECT_DOUBLE_EQ(usable_range_m(s, o), 0.5);
  EXPECT_FALSE(laser_beam(s, 0, o)->has_return);
}

TEST(SensorModelTest, BadReadingsAreIgnoredPerBeam) {
  LaserScan s = one_beam({0, 0, 0}, 1.0);
  s.ranges_m = {std::numeric_limits<double>::quiet_NaN(), -1.0, 0.01, 1.0, -std::numeric_limits<double>::infinity()};
  const SensorModelOptions o;
  EXPECT_FALSE(laser_beam(s, 0, o));  // NaN
  EXPECT_FALSE(laser_beam(s, 1, o));  // negative
  EXPECT_FALSE(laser_beam(s, 2, o));  // below range_min
  EXPECT_TRUE(laser_beam(s, 3, o));
  EXPECT_FALSE(laser_beam(s, 4, o));
  EXPECT_THROW(laser_beam(s, 5, o), std::out_of_range);
}

TEST(SensorModelTest, LaserBeamAnglesFollowPoseAndIncrement) {
  LaserScan s = one_beam({1.0, 2.0, 0.3}, 1.0);
  s.angle_min_rad = -0.5;
  s.angle_increment_rad = 0.25;
  s.ranges_m = {1.0, 1.0, 1.0};
  const auto b = laser_beam(s, 2, SensorModelOptions{});
  ASSERT_TRUE(b);
  EXPECT_NEAR(b->angle_rad, 0.3 - 0.5 + 2 * 0.25, 1e-12);
  EXPECT_NEAR(b->half_width_rad, 1.0 * kDeg, 1e-12);
  EXPECT_EQ(b->origin_m, Eigen::Vector2d(1.0, 2.0));
}

// From a cell corner, a 2° laser beam along +x: free space on its axis line (row 0), the return across the cone
// (both rows it starts between).
TEST(SensorModelTest, WideLaserBeamFreesItsAxisAndMarksTheReturnAcrossTheCone) {
  const auto cells = cells_of(one_beam({0.0, 0.0, 0.0}, 1.01), SensorModelOptions{});
  std::set<std::pair<std::int64_t, std::int64_t>> expected_free;
  for (std::int64_t x = 0; x < 20; ++x) expected_free.insert({x, 0});
  EXPECT_EQ(keys(cells, false), expected_free);
  EXPECT_EQ(keys(cells, true), (std::set<std::pair<std::int64_t, std::int64_t>>{{20, -1}, {20, 0}}));
  // The return cell: g = 1. Its neighbour across the axis (centre half a cell off it: angular weight 1) has the
  // Gaussian in range, d = √(20.5² + 0.5²) cells against r = 20.2, σ_e² = 0.29 cells².
  const double d = std::sqrt(20.5 * 20.5 + 0.25);
  for (const BeamCell& c : cells) {
    if (!c.hit) continue;
    EXPECT_NEAR(c.m_occupied, 0.9 * (c.cell.y == 0 ? 1.0 : std::exp(-(d - 20.2) * (d - 20.2) / (2 * 0.29))), 1e-9);
  }
}

// Far out, the laser's return arc spans the cone but fades with the beam profile: full on the axis, about
// exp(−2) = 0.135 at the cone's edge.
TEST(SensorModelTest, WideLaserReturnFadesTowardsTheConeEdge) {
  const auto cells = cells_of(one_beam({0.025, 0.025, 0.0}, 5.01), SensorModelOptions{});
  double edge_weight = 1.0;
  std::size_t hits = 0;
  for (const BeamCell& c : cells) {
    if (!c.hit) {
      EXPECT_EQ(c.cell.y, 0) << "free space only on the axis";
      continue;
    }
    ++hits;
    if (c.cell.y == 0) {
      EXPECT_NEAR(c.bayes_log_odds, logit(0.5 + 0.2 * c.m_occupied / 0.9), 1e-6);  // on the axis: weight 1
    }
    if (std::abs(c.cell.y) == 1) edge_weight = std::min(edge_weight, c.m_occupied / 0.9);
    EXPECT_LE(std::abs(c.cell.y), 2);  // ±1° at 5 m is ±0.087 m: rows −2 … 1 around the axis row
  }
  EXPECT_GE(hits, 4u);
  EXPECT_LT(edge_weight, 0.8);
}

// Angular span of a cell square as seen from p (p outside the square), relative to `axis` [rad].
std::pair<double, double> angular_span(double x0, double y0, double res, Eigen::Vector2d p, double axis) {
  double lo = 10, hi = -10;
  for (const double cx : {x0, x0 + res}) {
    for (const double cy : {y0, y0 + res}) {
      const double a = std::remainder(std::atan2(cy - p.y(), cx - p.x()) - axis, 2 * std::numbers::pi);
      lo = std::min(lo, a);
      hi = std::max(hi, a);
    }
  }
  return {lo, hi};
}

// A uniform cone (a sonar of 10°), checked by brute force against every cell around it: cells whose centres lie
// inside the cone are covered, and every covered cell meets the cone.
TEST(SensorModelTest, WideConeCoversExactlyTheCellsOfItsCone) {
  constexpr double kHalf = 5.0 * kDeg;
  for (const double axis : {0.0, 0.3, 0.7854, 1.2, 2.0, 3.0, -2.5, -0.9}) {
    const Eigen::Vector2d p(0.013, -0.031);
    const double reading = 4.0;
    SonarScan s;
    s.sensor_pose = {p.x(), p.y(), axis};
    s.angles_rad = {0.0};
    s.ranges_m = {reading};
    s.beam_width_rad = 2 * kHalf;
    s.range_max_m = 6.0;
    s.sigma_range_m = 0.0;
    SensorModelOptions o;
    o.sonar_sigma_per_range = 0.0;  // h = half a cell
    const auto cells = beam_cells(*sonar_beam(s, 0, o), kRes);
    std::set<std::pair<std::int64_t, std::int64_t>> covered;
    for (const BeamCell& c : cells) {
      EXPECT_TRUE(covered.insert({c.cell.x, c.cell.y}).second) << "cell visited twice";
      const double x0 = static_cast<double>(c.cell.x) * kRes;
      const double y0 = static_cast<double>(c.cell.y) * kRes;
      const bool contains_sensor = p.x() >= x0 && p.x() < x0 + kRes && p.y() >= y0 && p.y() < y0 + kRes;
      if (contains_sensor) continue;
      const auto [lo, hi] = angular_span(x0, y0, kRes, p, axis);
      EXPECT_TRUE(lo <= kHalf + 1e-9 && hi >= -kHalf - 1e-9)
          << "axis " << axis << ": cell " << c.cell.x << "," << c.cell.y << " is outside the cone";
      EXPECT_LE(c.distance_m, reading + 0.0354 + 1e-9);
    }
    const double free_limit = reading - 0.5 * kRes;  // h = max(σ, cell/2) = cell/2
    for (std::int64_t x = -100; x <= 100; ++x) {
      for (std::int64_t y = -100; y <= 100; ++y) {
        const Eigen::Vector2d c((static_cast<double>(x) + 0.5) * kRes, (static_cast<double>(y) + 0.5) * kRes);
        const double d = (c - p).norm();
        const double off = std::remainder(std::atan2(c.y() - p.y(), c.x() - p.x()) - axis, 2 * std::numbers::pi);
        if (d < free_limit && std::abs(off) < kHalf) {
          EXPECT_TRUE(covered.count({x, y})) << "axis " << axis << ": cell " << x << "," << y << " missed";
        }
      }
    }
    // At 4 m the 10° cone is 0.7 m wide: the return arc spans about 14 cells.
    EXPECT_GE(keys(cells, true).size(), 12u) << "axis " << axis;
  }
}

// Thin beams in many directions: a connected line of cells from the sensor's cell, each once, ending in a hit on
// the cell that holds the return point.
TEST(SensorModelTest, ThinBeamsAreConnectedLinesEndingInTheReturnCell) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(-1.0, 1.0), angle(-std::numbers::pi, std::numbers::pi), range(0.05, 6.0);
  for (int n = 0; n < 500; ++n) {
    const Pose2D pose{pos(rng), pos(rng), angle(rng)};
    const double r = range(rng);
    const auto cells = cells_of(one_beam(pose, r), thin());
    ASSERT_FALSE(cells.empty());
    const CellIndex start{static_cast<std::int64_t>(std::floor(pose.x_m / kRes)),
                          static_cast<std::int64_t>(std::floor(pose.y_m / kRes))};
    EXPECT_EQ(cells.front().cell, start);
    const CellIndex end{static_cast<std::int64_t>(std::floor((pose.x_m + r * std::cos(pose.theta_rad)) / kRes)),
                        static_cast<std::int64_t>(std::floor((pose.y_m + r * std::sin(pose.theta_rad)) / kRes))};
    bool end_hit = false;
    std::set<std::pair<std::int64_t, std::int64_t>> seen;
    for (const BeamCell& c : cells) {
      EXPECT_TRUE(seen.insert({c.cell.x, c.cell.y}).second);
      end_hit = end_hit || (c.hit && c.cell == end);
      EXPECT_LE(c.distance_m, r + 0.0354 + 1e-9);
    }
    // 8-connected: a flood fill from the sensor's cell reaches every cell.
    std::set<std::pair<std::int64_t, std::int64_t>> reached{{start.x, start.y}};
    std::vector<std::pair<std::int64_t, std::int64_t>> todo{{start.x, start.y}};
    while (!todo.empty()) {
      const auto [x, y] = todo.back();
      todo.pop_back();
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          if (seen.count({x + dx, y + dy}) && reached.insert({x + dx, y + dy}).second) todo.push_back({x + dx, y + dy});
        }
      }
    }
    EXPECT_EQ(reached.size(), seen.size()) << "pose " << pose.x_m << "," << pose.y_m << "," << pose.theta_rad;
    EXPECT_TRUE(end_hit) << "pose " << pose.x_m << "," << pose.y_m << "," << pose.theta_rad << " r " << r;
  }
}

TEST(SensorModelTest, SonarConeMarksTheArcAndFreesInside) {
  SonarScan s;
  s.sensor_pose = {0.025, 0.025, std::numbers::pi / 2};  // looking along +y
  s.angles_rad = {0.0};
  s.ranges_m = {2.0};
  s.beam_width_rad = 25.0 * kDeg;
  s.range_max_m = 6.0;
  const SensorModelOptions o;
  const auto beam = sonar_beam(s, 0, o);
  ASSERT_TRUE(beam);
  EXPECT_NEAR(beam->sigma_m, 0.02 + 0.01 * 2.0, 1e-12);
  const auto cells = beam_cells(*beam, kRes);
  // The arc: 2·2 m·tan(12.5°) ≈ 0.89 m ≈ 18 cells across.
  const auto hits = keys(cells, true);
  std::int64_t min_x = 1000, max_x = -1000;
  for (const auto& [x, y] : hits) {
    min_x = std::min(min_x, x);
    max_x = std::max(max_x, x);
  }
  EXPECT_LE(min_x, -8);
  EXPECT_GE(max_x, 8);
  for (const BeamCell& c : cells) {
    const Eigen::Vector2d center((static_cast<double>(c.cell.x) + 0.5) * kRes,
                                 (static_cast<double>(c.cell.y) + 0.5) * kRes);
    const double d = (center - Eigen::Vector2d(0.025, 0.025)).norm();
    if (c.hit) {
      EXPECT_NEAR(d, 2.0, 0.0401 + 1e-9);  // h = σ = 4 cm
      EXPECT_NEAR(c.bayes_log_odds,
                  logit(0.5 + 0.1 * std::exp(-std::pow(d - 2.0, 2) / (2 * (0.04 * 0.04 + 0.025 * 0.025)))), 1e-6);
    } else {
      EXPECT_LT(d, 2.0 - 0.04);
      EXPECT_NEAR(c.bayes_log_odds, logit(0.45), 1e-12);
    }
  }
  // Inside the cone, 1 m out, the whole width (±0.22 m) is free.
  const auto free = keys(cells, false);
  for (std::int64_t x = -3; x <= 3; ++x) EXPECT_TRUE(free.count({x, 20})) << x;
}

TEST(SensorModelTest, BeamCellsRejectsBadInput) {
  Beam b;
  b.range_m = 1.0;
  EXPECT_THROW(beam_cells(b, 0.0), std::invalid_argument);
  b.half_width_rad = 0.8;
  EXPECT_THROW(beam_cells(b, kRes), std::invalid_argument);
  b.half_width_rad = 0.0;
  b.angle_rad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(beam_cells(b, kRes), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
