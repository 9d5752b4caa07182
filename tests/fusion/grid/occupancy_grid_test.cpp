#include "fusion/grid/occupancy_grid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

namespace wm::fusion {
namespace {

constexpr double kRes = 0.05;
constexpr double kDeg = std::numbers::pi / 180.0;

double logit(double p) { return std::log(p / (1.0 - p)); }

GridOptions thin_options() {
  GridOptions o;
  o.sensor.laser_beam_width_rad = 0.0;
  return o;
}

LaserScan scan_at(Pose2D pose, std::vector<double> ranges, double angle_min = 0.0, double increment = 0.0) {
  LaserScan s;
  s.sensor_pose = pose;
  s.angle_min_rad = angle_min;
  s.angle_increment_rad = increment;
  s.ranges_m = std::move(ranges);
  s.range_min_m = 0.02;
  s.range_max_m = 30.0;
  s.sigma_range_m = 0.01;
  return s;
}

void expect_masses(const OccupancyGrid::Masses& m, double o, double e, double tol = 1e-6) {
  EXPECT_NEAR(m.occupied, o, tol);
  EXPECT_NEAR(m.empty, e, tol);
  EXPECT_NEAR(m.unknown, 1.0 - o - e, tol);
}

TEST(OccupancyGridTest, RejectsInvalidOptions) {
  auto bad = [](auto mutate) {
    GridOptions o;
    mutate(o);
    return o;
  };
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) { o.resolution_m = 0.0; })), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) { o.resolution_m = 1e-4; })), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) { o.tile_size_cells = 48; })), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) { o.tile_size_cells = 2048; })), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) { o.log_odds_min = 0.0; })), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) { o.log_odds_max = std::numeric_limits<double>::infinity(); })),
               std::invalid_argument);
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) { o.sensor.p_hit = 0.3; })), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) { o.ds_unknown_min = 1.0; })), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid(bad([](auto& o) {
                 o.update_bayes = false;
                 o.update_ds = false;
               })),
               std::invalid_argument);
}

TEST(OccupancyGridTest, EmptyGridIsUnknownEverywhere) {
  const OccupancyGrid grid{GridOptions{}};
  EXPECT_FALSE(grid.bounds());
  EXPECT_TRUE(grid.tiles().empty());
  EXPECT_DOUBLE_EQ(grid.log_odds({3, -7}), 0.0);
  EXPECT_DOUBLE_EQ(grid.probability({3, -7}), 0.5);
  expect_masses(grid.masses({3, -7}), 0.0, 0.0);
  EXPECT_DOUBLE_EQ(grid.belief({0, 0}), 0.0);
  EXPECT_DOUBLE_EQ(grid.plausibility({0, 0}), 1.0);
  EXPECT_DOUBLE_EQ(grid.conflict({0, 0}), 0.0);
  EXPECT_FALSE(grid.tile({0, 0}));
}

TEST(OccupancyGridTest, OneBeamUpdatesFreeCellsAndTheHit) {
  OccupancyGrid grid(thin_options());
  grid.insert(scan_at({0.025, 0.025, 0.0}, {1.01}));
  for (std::int64_t x = 0; x < 20; ++x) {
    EXPECT_NEAR(grid.log_odds({x, 0}), logit(0.4), 1e-6) << x;
    EXPECT_LT(grid.probability({x, 0}), 0.5);
  }
  EXPECT_NEAR(grid.log_odds({20, 0}), logit(0.7), 1e-6);
  EXPECT_NEAR(grid.probability({20, 0}), 0.7, 1e-6);
  EXPECT_DOUBLE_EQ(grid.log_odds({21, 0}), 0.0);
  EXPECT_DOUBLE_EQ(grid.log_odds({5, 1}), 0.0);
  expect_masses(grid.masses({3, 0}), 0.0, 0.9);
  // The hit's (0.9, 0.09, 0.01) is discounted to m(Θ) = ds_unknown_min = 0.05.
  const double s = 0.95 / 0.99;
  expect_masses(grid.masses({20, 0}), 0.9 * s, 0.09 * s);
  EXPECT_NEAR(grid.belief({20, 0}), 0.9 * s, 1e-6);
  EXPECT_NEAR(grid.plausibility({20, 0}), 1.0 - 0.09 * s, 1e-6);
  EXPECT_NEAR(grid.plausibility({3, 0}), 0.1, 1e-6);
}

TEST(OccupancyGridTest, BadReadingsAreSkippedPerBeamNotPerScan) {
  OccupancyGrid grid(thin_options());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // Beams at 0, 90°, 180°, 270°: only the 90° one is valid.
  grid.insert(scan_at({0.025, 0.025, 0.0}, {nan, 0.51, -1.0, 0.001}, 0.0, std::numbers::pi / 2));
  EXPECT_NEAR(grid.log_odds({0, 10}), logit(0.7), 1e-6);
  EXPECT_NEAR(grid.log_odds({0, 5}), logit(0.4), 1e-6);
  EXPECT_DOUBLE_EQ(grid.log_odds({5, 0}), 0.0);
  EXPECT_DOUBLE_EQ(grid.log_odds({-5, 0}), 0.0);
  EXPECT_DOUBLE_EQ(grid.log_odds({0, -5}), 0.0);
}

TEST(OccupancyGridTest, HitWinsOverMissInSameScan) {
  // Two beams along +x: one returns in cell 10, the other passes through it to cell 20.
  GridOptions o = thin_options();
  o.ds_unknown_min = 0.0;  // plain Dempster, to compare with dempster_combine
  for (const std::vector<double>& ranges : {std::vector<double>{0.51, 1.01}, std::vector<double>{1.01, 0.51}}) {
    OccupancyGrid grid(o);
    grid.insert(scan_at({0.025, 0.025, 0.0}, ranges));
    EXPECT_NEAR(grid.log_odds({10, 0}), logit(0.7), 1e-6);  // the hit only, not hit + miss
    EXPECT_NEAR(grid.log_odds({5, 0}), logit(0.4), 1e-6);   // freed once although two beams crossed it
    EXPECT_NEAR(grid.log_odds({20, 0}), logit(0.7), 1e-6);
    // DS: the scan's two opinions of cell 10 are combined first — hit (0.9, 0.09) ⊕ free (m_O = 0.9·g, with the
    // far return 10 cells behind it, g = 0: (0, 0.9)) — then combined into the empty cell (no conflict).
    const DempsterResult in_scan = dempster_combine({0.9, 0.09, 0.01}, {0.0, 0.9, 0.1});
    ASSERT_TRUE(in_scan.masses);
    expect_masses(grid.masses({10, 0}), in_scan.masses->occupied, in_scan.masses->empty);
    EXPECT_DOUBLE_EQ(grid.conflict({10, 0}), 0.0);
  }
}

TEST(OccupancyGridTest, ManyBeamsThroughOneCellUpdateItOncePerScan) {
  // 200 beams 0.001° apart share their cells for many metres: each cell is freed (or hit) once per scan.
  GridOptions o = thin_options();
  o.ds_unknown_min = 0.0;
  OccupancyGrid grid(o);
  const LaserScan s = scan_at({0.025, 0.025, 0.0}, std::vector<double>(200, 1.01), 0.0, 0.001 * kDeg);
  grid.insert(s);
  EXPECT_NEAR(grid.log_odds({5, 0}), logit(0.4), 1e-6);
  EXPECT_NEAR(grid.log_odds({20, 0}), logit(0.7), 1e-6);
  // DS: a scan's free opinions (0, 0.9) of a cell are combined with each other first, then into the cell once:
  // n of them give m(E) = 1 − 0.1ⁿ (no mass on O, so no conflict), here with three beams.
  OccupancyGrid three(o);
  three.insert(scan_at({0.025, 0.025, 0.0}, {1.01, 1.01, 1.01}, 0.0, 0.001 * kDeg));
  expect_masses(three.masses({5, 0}), 0.0, 0.999);
  grid.insert(s);
  EXPECT_NEAR(grid.log_odds({5, 0}), 2 * logit(0.4), 1e-5);
  EXPECT_NEAR(grid.log_odds({20, 0}), 2 * logit(0.7), 1e-5);
}

TEST(OccupancyGridTest, TheTileSizeDoesNotChangeTheCells) {
  // Tiles of 4 cells: one scan touches hundreds of them (more than the grid keeps scratch for between scans).
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> range(0.5, 12.0);
  std::vector<LaserScan> scans;
  for (int k = 0; k < 6; ++k) {
    std::vector<double> ranges(361);
    for (double& r : ranges) r = range(rng);
    scans.push_back(scan_at({0.3 * k, -0.2 * k, 0.1 * k}, ranges, -std::numbers::pi, kDeg));
  }
  GridOptions small;
  small.tile_size_cells = 4;
  OccupancyGrid a(small);
  OccupancyGrid b{GridOptions{}};
  for (const LaserScan& s : scans) {
    a.insert(s);
    b.insert(s);
  }
  EXPECT_GT(a.tiles().size(), 1000u);
  const GridGeometry region = *b.bounds();
  for (const auto layer : {OccupancyGrid::Layer::bayes_probability, OccupancyGrid::Layer::ds_belief,
                           OccupancyGrid::Layer::ds_plausibility, OccupancyGrid::Layer::ds_conflict}) {
    const std::vector<float> va = a.export_layer(layer, region);
    const std::vector<float> vb = b.export_layer(layer, region);
    ASSERT_EQ(va.size(), vb.size());
    std::size_t known = 0, differ = 0;
    for (std::size_t i = 0; i < va.size(); ++i) {
      if (std::isnan(va[i]) != std::isnan(vb[i]) || (!std::isnan(va[i]) && va[i] != vb[i])) ++differ;
      if (!std::isnan(vb[i])) ++known;
    }
    EXPECT_EQ(differ, 0u);
    EXPECT_GT(known, 10000u);
  }
}

TEST(OccupancyGridTest, RepeatedScansAccumulateAndClamp) {
  GridOptions o = thin_options();
  OccupancyGrid grid(o);
  const LaserScan s = scan_at({0.025, 0.025, 0.0}, {1.01});
  grid.insert(s);
  grid.insert(s);
  EXPECT_NEAR(grid.log_odds({20, 0}), 2 * logit(0.7), 1e-5);
  EXPECT_NEAR(grid.log_odds({3, 0}), 2 * logit(0.4), 1e-5);
  // (0, .9, .1) ⊕ (0, .9, .1) = (0, .99, .01), discounted to m(Θ) = ds_unknown_min = 0.05.
  expect_masses(grid.masses({3, 0}), 0.0, 0.95);
  for (int i = 0; i < 20; ++i) grid.insert(s);
  EXPECT_FLOAT_EQ(static_cast<float>(grid.log_odds({20, 0})), 3.5f);
  EXPECT_FLOAT_EQ(static_cast<float>(grid.log_odds({3, 0})), -2.0f);
  // Clamped cells react to new evidence at once (OctoMap's point of clamping).
  grid.insert(scan_at({0.025, 0.025, 0.0}, {2.01}));
  EXPECT_NEAR(grid.log_odds({20, 0}), 3.5 + logit(0.4), 1e-5);
}

TEST(OccupancyGridTest, ConflictLayerKeepsTheLargestConflict) {
  GridOptions o = thin_options();
  o.ds_unknown_min = 0.0;  // plain Dempster, to check against the hand computation
  OccupancyGrid grid(o);
  grid.insert(scan_at({0.025, 0.025, 0.0}, {2.01}));  // cell 20 free: (0, 0.9)
  expect_masses(grid.masses({20, 0}), 0.0, 0.9);
  grid.insert(scan_at({0.025, 0.025, 0.0}, {1.01}));  // now hit: (0.9, 0.09)
  // K = 0·0.09 + 0.9·0.9 = 0.81; m(O) = 0.9·0.1/0.19, m(E) = (0.9·0.09 + 0.9·0.01 + 0.1·0.09)/0.19.
  EXPECT_NEAR(grid.conflict({20, 0}), 0.81, 1e-6);
  expect_masses(grid.masses({20, 0}), 0.09 / 0.19, (0.081 + 0.009 + 0.009) / 0.19);
  grid.insert(scan_at({0.025, 0.025, 0.0}, {2.01}));  // a smaller conflict does not lower the layer
  EXPECT_NEAR(grid.conflict({20, 0}), 0.81, 1e-6);
  EXPECT_DOUBLE_EQ(grid.conflict({3, 0}), 0.0);
}

TEST(OccupancyGridTest, DsCellsStayRevisableAfterLongFreeEvidence) {
  const LaserScan through = scan_at({0.025, 0.025, 0.0}, {2.01});  // cell 20 free
  const LaserScan onto = scan_at({0.025, 0.025, 0.0}, {1.01});     // cell 20 hit
  GridOptions plain = thin_options();
  plain.ds_unknown_min = 0.0;
  OccupancyGrid discounted(thin_options()), stubborn(plain);
  for (int i = 0; i < 30; ++i) {
    discounted.insert(through);
    stubborn.insert(through);
  }
  expect_masses(discounted.masses({20, 0}), 0.0, 0.95);
  for (int i = 0; i < 3; ++i) {
    discounted.insert(onto);
    stubborn.insert(onto);
  }
  EXPECT_GT(discounted.belief({20, 0}), 0.5);  // the wall that appeared is seen
  EXPECT_LT(stubborn.belief({20, 0}), 0.01);   // plain Dempster: m(E) ≈ 1 outvotes any number of hits
  // The discount keeps m(Θ) at the floor, never below.
  EXPECT_NEAR(discounted.masses({20, 0}).unknown, 0.05, 1e-6);
}

TEST(DempsterTest, CombinesAWorkedExample) {
  // K = 0.6·0.2 + 0.3·0.5 = 0.27; m(O) = (0.30 + 0.18 + 0.05)/0.73; m(E) = (0.06 + 0.09 + 0.02)/0.73.
  const DempsterResult r = dempster_combine({0.6, 0.3, 0.1}, {0.5, 0.2, 0.3});
  EXPECT_NEAR(r.conflict, 0.27, 1e-12);
  ASSERT_TRUE(r.masses);
  EXPECT_NEAR(r.masses->occupied, 0.53 / 0.73, 1e-12);
  EXPECT_NEAR(r.masses->empty, 0.17 / 0.73, 1e-12);
  EXPECT_NEAR(r.masses->unknown, 0.03 / 0.73, 1e-12);
  const DempsterResult swapped = dempster_combine({0.5, 0.2, 0.3}, {0.6, 0.3, 0.1});
  EXPECT_NEAR(swapped.masses->occupied, r.masses->occupied, 1e-12);
}

TEST(DempsterTest, VacuousMassIsNeutral) {
  const DempsterResult r = dempster_combine({0.0, 0.0, 1.0}, {0.2, 0.7, 0.1});
  EXPECT_DOUBLE_EQ(r.conflict, 0.0);
  ASSERT_TRUE(r.masses);
  EXPECT_NEAR(r.masses->occupied, 0.2, 1e-12);
  EXPECT_NEAR(r.masses->empty, 0.7, 1e-12);
  EXPECT_NEAR(r.masses->unknown, 0.1, 1e-12);
}

TEST(DempsterTest, AgreeingSourcesReinforce) {
  // (0.8, 0, 0.2) ⊕ (0.8, 0, 0.2): no conflict, m(O) = 0.64 + 0.16 + 0.16 = 0.96.
  const DempsterResult r = dempster_combine({0.8, 0.0, 0.2}, {0.8, 0.0, 0.2});
  EXPECT_DOUBLE_EQ(r.conflict, 0.0);
  EXPECT_NEAR(r.masses->occupied, 0.96, 1e-12);
  EXPECT_NEAR(r.masses->unknown, 0.04, 1e-12);
}

TEST(DempsterTest, TotalConflictHasNoMasses) {
  const DempsterResult r = dempster_combine({1.0, 0.0, 0.0}, {0.0, 1.0, 0.0});
  EXPECT_FALSE(r.masses);
  EXPECT_DOUBLE_EQ(r.conflict, 1.0);
}

TEST(DempsterTest, RejectsInvalidMasses) {
  EXPECT_THROW(dempster_combine({0.5, 0.6, 0.1}, {0, 0, 1}), std::invalid_argument);
  EXPECT_THROW(dempster_combine({0, 0, 1}, {-0.1, 0.6, 0.5}), std::invalid_argument);
  EXPECT_THROW(dempster_combine({std::numeric_limits<double>::quiet_NaN(), 0, 1}, {0, 0, 1}), std::invalid_argument);
}

// A rectangular room [x0, x0 + w] × [y0, y0 + h], offset from the cell borders.
struct Room {
  double x0 = 0.013, y0 = -0.021, w = 6.0, h = 4.0;

  // Exact distance from p along direction a to the walls (p inside).
  double cast(Eigen::Vector2d p, double a) const {
    const double ux = std::cos(a), uy = std::sin(a);
    double t = std::numeric_limits<double>::infinity();
    if (ux > 1e-12) t = std::min(t, (x0 + w - p.x()) / ux);
    if (ux < -1e-12) t = std::min(t, (x0 - p.x()) / ux);
    if (uy > 1e-12) t = std::min(t, (y0 + h - p.y()) / uy);
    if (uy < -1e-12) t = std::min(t, (y0 - p.y()) / uy);
    return t;
  }
  double distance_to_walls(Eigen::Vector2d q) const {
    return std::min({std::abs(q.x() - x0), std::abs(q.x() - x0 - w), std::abs(q.y() - y0), std::abs(q.y() - y0 - h)});
  }
  bool inside(Eigen::Vector2d q) const { return q.x() > x0 && q.x() < x0 + w && q.y() > y0 && q.y() < y0 + h; }
};

// A laser scan of a known room, ray-cast exactly from poses inside, with fixed-seed Gaussian range noise: walls
// end up occupied within one cell of every true return, and the inside free, in both models.
TEST(OccupancyGridTest, SyntheticRoomHasOccupiedWallsAndFreeInside) {
  const Room room;
  OccupancyGrid grid{GridOptions{}};  // default 2° laser cone
  std::mt19937 rng(42);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<Eigen::Vector2d> returns;
  const std::vector<Pose2D> poses = {
      {1.5, 1.0, 0.3}, {3.0, 2.0, -1.0}, {4.7, 3.1, 2.0}, {2.2, 3.0, 0.0}, {5.1, 0.8, 1.2}};
  for (const Pose2D& pose : poses) {
    LaserScan s = scan_at(pose, {}, -std::numbers::pi, 1.0 * kDeg);
    for (int i = 0; i < 360; ++i) {
      const double a = pose.theta_rad + s.angle_min_rad + i * s.angle_increment_rad;
      const double t = room.cast({pose.x_m, pose.y_m}, a);
      s.ranges_m.push_back(t + noise(rng));
      returns.push_back(Eigen::Vector2d(pose.x_m, pose.y_m) + t * Eigen::Vector2d(std::cos(a), std::sin(a)));
    }
    grid.insert(s);
  }
  const GridGeometry cells({0, 0}, kRes, 1, 1);

  // Every true return has an occupied cell (Bayes p > 0.5 and DS belief > 0.5) within one cell.
  int bayes_found = 0, ds_found = 0;
  for (const Eigen::Vector2d& q : returns) {
    const CellIndex c = cells.cell_of(q);
    bool bayes = false, ds = false;
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        bayes = bayes || grid.probability({c.x + dx, c.y + dy}) > 0.5;
        ds = ds || grid.belief({c.x + dx, c.y + dy}) > 0.5;
      }
    }
    bayes_found += bayes;
    ds_found += ds;
  }
  EXPECT_EQ(bayes_found, static_cast<int>(returns.size()));
  EXPECT_EQ(ds_found, static_cast<int>(returns.size()));

  // Inside, more than one cell from the walls, every observed cell is free, in both models.
  int inside = 0, bayes_free = 0, ds_free = 0;
  for (std::int64_t x = 0; x < 121; ++x) {
    for (std::int64_t y = -1; y < 80; ++y) {
      const Eigen::Vector2d q = cells.center_of({x, y});
      if (!room.inside(q) || room.distance_to_walls(q) <= 1.5 * kRes) continue;
      ++inside;
      bayes_free += grid.probability({x, y}) < 0.5;
      EXPECT_LT(grid.probability({x, y}), 0.5)
          << "cell " << x << "," << y << ", " << room.distance_to_walls(q) << " m from a wall";
      const auto m = grid.masses({x, y});
      ds_free += m.empty > m.occupied && grid.plausibility({x, y}) < 0.5;
    }
  }
  EXPECT_GT(inside, 9000);
  EXPECT_EQ(bayes_free, inside);
  EXPECT_EQ(ds_free, inside);

  // Outside the room nothing was seen.
  EXPECT_DOUBLE_EQ(grid.log_odds(cells.cell_of({room.x0 + 3.0, room.y0 + room.h + 0.3})), 0.0);
  EXPECT_DOUBLE_EQ(grid.masses(cells.cell_of({room.x0 - 0.3, room.y0 + 2.0})).unknown, 1.0);
}

TEST(OccupancyGridTest, GrowsIntoNewTilesAndLeavesTheFirstRegionUnchanged) {
  OccupancyGrid grid{GridOptions{}};
  const LaserScan first = scan_at({0.5, 0.5, 0.0}, std::vector<double>(90, 2.0), -std::numbers::pi / 4, 1.0 * kDeg);
  grid.insert(first);
  const std::vector<TileIndex> first_tiles = grid.tiles();
  EXPECT_EQ(grid.take_dirty_tiles(), first_tiles);
  EXPECT_TRUE(grid.take_dirty_tiles().empty());
  const GridGeometry region = *grid.bounds();
  const auto before = grid.export_layer(OccupancyGrid::Layer::bayes_probability, region);
  const auto before_ds = grid.export_layer(OccupancyGrid::Layer::ds_belief, region);

  // Far away and at negative coordinates.
  LaserScan second = first;
  second.sensor_pose = {-100.0, -50.0, 2.0};
  grid.insert(second);
  const std::vector<TileIndex> dirty = grid.take_dirty_tiles();
  ASSERT_FALSE(dirty.empty());
  for (const TileIndex& t : dirty) {
    EXPECT_LT(t.x, 0);
    EXPECT_LT(t.y, 0);
    EXPECT_FALSE(std::binary_search(first_tiles.begin(), first_tiles.end(), t));
  }
  EXPECT_EQ(grid.tiles().size(), first_tiles.size() + dirty.size());
  const auto after = grid.export_layer(OccupancyGrid::Layer::bayes_probability, region);
  const auto after_ds = grid.export_layer(OccupancyGrid::Layer::ds_belief, region);
  ASSERT_EQ(before.size(), after.size());
  for (std::size_t i = 0; i < before.size(); ++i) {
    EXPECT_TRUE(before[i] == after[i] || (std::isnan(before[i]) && std::isnan(after[i]))) << i;
    EXPECT_TRUE(before_ds[i] == after_ds[i] || (std::isnan(before_ds[i]) && std::isnan(after_ds[i]))) << i;
  }
  // The bounds now cover both places.
  const GridGeometry b = *grid.bounds();
  EXPECT_LE(b.origin_m().x(), -102.0);
  EXPECT_LE(b.origin_m().y(), -50.0);
  EXPECT_GE(b.origin_m().x() + b.resolution_m() * static_cast<double>(b.width()), 2.5);
  EXPECT_EQ(b.width() % grid.tile_size_cells(), 0);
}

TEST(OccupancyGridTest, ATileRevisionCountsTheInsertsThatChangedItAndNothingElse) {
  OccupancyGrid grid{GridOptions{}};
  const LaserScan here = scan_at({0.5, 0.5, 0.0}, std::vector<double>(90, 2.0), -std::numbers::pi / 4, 1.0 * kDeg);
  grid.insert(here);
  const auto first = grid.tile_revisions();
  ASSERT_FALSE(first.empty());
  for (const auto& [tile, revision] : first) EXPECT_EQ(revision, 1u);
  LaserScan far = here;
  far.sensor_pose = {-100.0, -50.0, 2.0};
  grid.insert(far);
  grid.insert(here);
  for (const auto& [tile, revision] : first) EXPECT_EQ(grid.tile_revision(tile), 2u) << "untouched by the far scan";
  std::size_t far_tiles = 0;
  for (const auto& entry : grid.tile_revisions()) {  // not a structured binding: clang 14 cannot capture one
    if (std::find_if(first.begin(), first.end(), [&](const auto& f) { return f.first == entry.first; }) != first.end())
      continue;
    EXPECT_EQ(entry.second, 1u);
    ++far_tiles;
  }
  EXPECT_GT(far_tiles, 0u);
  EXPECT_EQ(grid.tile_revision({1000, 1000}), 0u);  // never touched
  // A restore changes the cells too.
  const auto t = first.front().first;
  grid.set_tile(t, *grid.tile(t));
  EXPECT_EQ(grid.tile_revision(t), 3u);
}

TEST(OccupancyGridTest, RefusesScansThatWouldGrowTheGridBeyondTheLimit) {
  OccupancyGrid grid{GridOptions{}};
  grid.insert(scan_at({0.0, 0.0, 0.0}, {1.0}));
  const auto tiles = grid.tiles();
  EXPECT_THROW(grid.insert(scan_at({60'000.0, 0.0, 0.0}, {1.0})), std::invalid_argument);  // 1.2 M cells away
  EXPECT_THROW(grid.insert(scan_at({1e300, 0.0, 0.0}, {1.0})), std::invalid_argument);
  EXPECT_EQ(grid.tiles(), tiles);  // nothing applied
  EXPECT_TRUE(grid.take_dirty_tiles().size() == tiles.size());
}

TEST(OccupancyGridTest, TileRoundTripIsExact) {
  OccupancyGrid grid{GridOptions{}};
  grid.insert(scan_at({0.3, -0.2, 0.4}, std::vector<double>(180, 3.0), -std::numbers::pi / 2, 1.0 * kDeg));
  grid.insert(scan_at({1.3, 0.2, 0.9}, std::vector<double>(180, 2.5), -std::numbers::pi / 2, 1.0 * kDeg));
  OccupancyGrid restored{GridOptions{}};
  for (const TileIndex& t : grid.tiles()) restored.set_tile(t, *grid.tile(t));
  EXPECT_EQ(restored.tiles(), grid.tiles());
  EXPECT_TRUE(restored.take_dirty_tiles().empty());  // restoring is not a change
  for (const TileIndex& t : grid.tiles()) {
    const auto a = *grid.tile(t);
    const auto b = *restored.tile(t);
    EXPECT_EQ(a.log_odds, b.log_odds);
    EXPECT_EQ(a.m_occupied, b.m_occupied);
    EXPECT_EQ(a.m_empty, b.m_empty);
    EXPECT_EQ(a.conflict, b.conflict);
  }
  const GridGeometry region = *grid.bounds();
  for (const auto layer : {OccupancyGrid::Layer::bayes_probability, OccupancyGrid::Layer::ds_belief,
                           OccupancyGrid::Layer::ds_plausibility, OccupancyGrid::Layer::ds_conflict}) {
    const auto a = grid.export_layer(layer, region);
    const auto b = restored.export_layer(layer, region);
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(a[i] == b[i] || (std::isnan(a[i]) && std::isnan(b[i])));
  }
  // The restored grid goes on updating like the original.
  const LaserScan more = scan_at({0.8, 0.0, 0.0}, std::vector<double>(90, 1.5), -0.8, 1.0 * kDeg);
  grid.insert(more);
  restored.insert(more);
  EXPECT_EQ(grid.tile(grid.tiles().front())->log_odds, restored.tile(grid.tiles().front())->log_odds);
}

TEST(OccupancyGridTest, ATilesLayersAreTheDenseExportOfItsRegionBitForBit) {
  OccupancyGrid grid{GridOptions{}};
  grid.insert(scan_at({0.3, -0.2, 0.4}, std::vector<double>(180, 3.0), -std::numbers::pi / 2, 1.0 * kDeg));
  grid.insert(scan_at({1.3, 0.2, 0.9}, std::vector<double>(180, 2.5), -std::numbers::pi / 2, 1.0 * kDeg));
  const auto n = static_cast<std::size_t>(grid.tile_size_cells() * grid.tile_size_cells());
  const OccupancyGrid::Layer layers[] = {OccupancyGrid::Layer::bayes_probability, OccupancyGrid::Layer::ds_belief,
                                         OccupancyGrid::Layer::ds_plausibility, OccupancyGrid::Layer::ds_conflict};
  std::size_t known = 0;
  ASSERT_GT(grid.tiles().size(), 1u);
  for (const TileIndex& t : grid.tiles()) {
    const auto all = grid.export_tile_layers(t);
    ASSERT_EQ(all.size(), 4 * n);
    for (std::size_t l = 0; l < 4; ++l) {
      const auto dense = grid.export_layer(layers[l], grid.tiles_geometry(t, t));
      ASSERT_EQ(dense.size(), n);
      for (std::size_t i = 0; i < n; ++i) {
        const float a = all[l * n + i];
        ASSERT_TRUE(std::memcmp(&a, &dense[i], sizeof a) == 0 || (std::isnan(a) && std::isnan(dense[i])))
            << "tile " << t.x << "," << t.y << " layer " << l << " cell " << i << ": " << a << " vs " << dense[i];
        known += std::isnan(a) ? 0 : 1;
      }
    }
  }
  EXPECT_GT(known, 1000u);
  const auto missing = grid.export_tile_layers({1000, 1000});  // never touched: unknown everywhere
  EXPECT_TRUE(std::all_of(missing.begin(), missing.end(), [](float v) { return std::isnan(v); }));
}

TEST(OccupancyGridTest, ACellReaderReadsWhatLogOddsReads) {
  OccupancyGrid grid{GridOptions{}};
  grid.insert(scan_at({0.3, -0.2, 0.4}, std::vector<double>(180, 3.0), -std::numbers::pi / 2, 1.0 * kDeg));
  grid.insert(scan_at({-2.0, 1.0, 2.0}, std::vector<double>(180, 4.0), -std::numbers::pi / 2, 1.0 * kDeg));
  OccupancyGrid::CellReader reader(grid);
  std::mt19937 random(7);
  std::uniform_int_distribution<std::int64_t> cell(-150, 150);
  std::size_t seen = 0;
  for (int i = 0; i < 20000; ++i) {
    // Runs of neighbours (the cache's case) and jumps across tiles, into tiles that do not exist too.
    const CellIndex c = i % 10 == 0 ? CellIndex{cell(random) * 3, cell(random) * 3} : CellIndex{cell(random), 7};
    ASSERT_EQ(reader.log_odds(c), grid.log_odds(c)) << c.x << "," << c.y;
    seen += grid.log_odds(c) != 0.0 ? 1 : 0;
  }
  EXPECT_GT(seen, 1000u);
}

TEST(OccupancyGridTest, SetTileRejectsBadData) {
  OccupancyGrid grid{GridOptions{}};
  const std::size_t n = 64 * 64;
  const OccupancyGrid::TileData good{std::vector<float>(n, 0.f), std::vector<float>(n, 0.f), std::vector<float>(n, 0.f),
                                     std::vector<float>(n, 0.f)};
  auto bad = [&](auto mutate) {
    OccupancyGrid::TileData d = good;
    mutate(d);
    return d;
  };
  EXPECT_THROW(grid.set_tile({0, 0}, bad([](auto& d) { d.log_odds.pop_back(); })), std::invalid_argument);
  EXPECT_THROW(grid.set_tile({0, 0}, bad([](auto& d) { d.conflict.push_back(0.f); })), std::invalid_argument);
  EXPECT_THROW(grid.set_tile({0, 0}, bad([](auto& d) { d.log_odds[7] = std::numeric_limits<float>::quiet_NaN(); })),
               std::invalid_argument);
  EXPECT_THROW(grid.set_tile({0, 0}, bad([](auto& d) { d.m_empty[7] = std::numeric_limits<float>::infinity(); })),
               std::invalid_argument);
  EXPECT_THROW(grid.set_tile({0, 0}, bad([](auto& d) {
                               d.m_occupied[3] = 0.7f;
                               d.m_empty[3] = 0.6f;
                             })),
               std::invalid_argument);
  EXPECT_THROW(grid.set_tile({0, 0}, bad([](auto& d) { d.conflict[3] = 1.5f; })), std::invalid_argument);
  EXPECT_TRUE(grid.tiles().empty());
  OccupancyGrid::TileData clamped = good;
  clamped.log_odds[0] = 9.f;
  grid.set_tile({-3, 2}, clamped);
  EXPECT_FLOAT_EQ(static_cast<float>(grid.log_odds({-3 * 64, 2 * 64})), 3.5f);
  EXPECT_EQ(grid.bounds()->origin_m(), Eigen::Vector2d(-3 * 64 * kRes, 2 * 64 * kRes));
}

TEST(OccupancyGridTest, ExportLayerIsRowMajorFromTheLowerLeftWithNanForUnknown) {
  OccupancyGrid grid(thin_options());
  grid.insert(scan_at({0.025, 0.025, std::numbers::pi / 2}, {0.21}));  // column x = 0, rows 0..4 (hit in 4)
  // Region: cells x ∈ [-1, 1], y ∈ [0, 5], aligned with the grid.
  const GridGeometry region({-kRes, 0.0}, kRes, 3, 6);
  const auto bayes = grid.export_layer(OccupancyGrid::Layer::bayes_probability, region);
  ASSERT_EQ(bayes.size(), 18u);
  for (std::int64_t row = 0; row < 6; ++row) {
    for (std::int64_t col = 0; col < 3; ++col) {
      const float v = bayes[static_cast<std::size_t>(row * 3 + col)];
      const CellIndex c{col - 1, row};
      if (col != 1 || row == 5) {
        EXPECT_TRUE(std::isnan(v)) << row << "," << col;
      } else {
        EXPECT_NEAR(v, grid.probability(c), 1e-6);
      }
    }
  }
  EXPECT_NEAR(bayes[4 * 3 + 1], 0.7, 1e-6);
  EXPECT_NEAR(bayes[0 * 3 + 1], 0.4, 1e-6);
  const auto belief = grid.export_layer(OccupancyGrid::Layer::ds_belief, region);
  const auto plaus = grid.export_layer(OccupancyGrid::Layer::ds_plausibility, region);
  const auto conflict = grid.export_layer(OccupancyGrid::Layer::ds_conflict, region);
  EXPECT_NEAR(belief[4 * 3 + 1], 0.9 * 0.95 / 0.99, 1e-6);  // discounted to m(Θ) = 0.05
  EXPECT_NEAR(plaus[1 * 3 + 1], 0.1, 1e-6);
  EXPECT_FLOAT_EQ(conflict[1 * 3 + 1], 0.f);
  EXPECT_TRUE(std::isnan(conflict[0]));
  // A coarser, unaligned region samples the cell under each centre.
  const GridGeometry coarse({-0.001, 0.0}, 0.1, 1, 1);  // centre (0.049, 0.05): cell (0, 1)
  EXPECT_NEAR(grid.export_layer(OccupancyGrid::Layer::bayes_probability, coarse)[0], 0.4, 1e-6);
  EXPECT_THROW(grid.export_layer(OccupancyGrid::Layer::ds_belief, GridGeometry({0, 0}, 0.05, 1'000'000, 1'000)),
               std::invalid_argument);
}

TEST(OccupancyGridTest, SonarConeMarksTheArcAndFreesInside) {
  OccupancyGrid grid{GridOptions{}};
  SonarScan s;
  s.sensor_pose = {0.025, 0.025, 0.0};
  s.angles_rad = {std::numbers::pi / 2};  // one transducer looking along +y
  s.ranges_m = {2.0};
  s.beam_width_rad = 25.0 * kDeg;
  s.range_max_m = 5.0;
  grid.insert(s);
  const GridGeometry cells({0, 0}, kRes, 1, 1);
  const Eigen::Vector2d sensor(0.025, 0.025);
  int arc = 0;
  for (int deg = -12; deg <= 12; ++deg) {
    const double a = std::numbers::pi / 2 + deg * kDeg;
    const CellIndex on_arc = cells.cell_of(sensor + 2.0 * Eigen::Vector2d(std::cos(a), std::sin(a)));
    EXPECT_GT(grid.probability(on_arc), 0.5) << deg;
    EXPECT_GT(grid.belief(on_arc), 0.4) << deg;
    arc += grid.probability(on_arc) > 0.5;
    const CellIndex inside = cells.cell_of(sensor + 1.2 * Eigen::Vector2d(std::cos(a), std::sin(a)));
    EXPECT_LT(grid.probability(inside), 0.5) << deg;
    EXPECT_GT(grid.masses(inside).empty, 0.8) << deg;
  }
  EXPECT_EQ(arc, 25);
  // Outside the cone and behind the arc: untouched.
  for (const double deg : {-20.0, 20.0}) {
    const double a = std::numbers::pi / 2 + deg * kDeg;
    EXPECT_DOUBLE_EQ(grid.log_odds(cells.cell_of(sensor + 1.5 * Eigen::Vector2d(std::cos(a), std::sin(a)))), 0.0);
  }
  EXPECT_DOUBLE_EQ(grid.log_odds(cells.cell_of(sensor + Eigen::Vector2d(0.0, 2.3))), 0.0);
}

TEST(OccupancyGridTest, SingleModelGridsLeaveTheOtherLayerUnknown) {
  GridOptions bayes_only = thin_options();
  bayes_only.update_ds = false;
  GridOptions ds_only = thin_options();
  ds_only.update_bayes = false;
  OccupancyGrid a(bayes_only), b(ds_only), both(thin_options());
  const LaserScan s = scan_at({0.025, 0.025, 0.0}, {1.01});
  a.insert(s);
  b.insert(s);
  both.insert(s);
  EXPECT_DOUBLE_EQ(a.log_odds({20, 0}), both.log_odds({20, 0}));
  EXPECT_DOUBLE_EQ(a.masses({20, 0}).unknown, 1.0);
  EXPECT_DOUBLE_EQ(b.log_odds({20, 0}), 0.0);
  EXPECT_DOUBLE_EQ(b.belief({20, 0}), both.belief({20, 0}));
}

TEST(OccupancyGridTest, CopiesAreIndependent) {
  OccupancyGrid grid(thin_options());
  grid.insert(scan_at({0.025, 0.025, 0.0}, {1.01}));
  OccupancyGrid copy = grid;
  copy.insert(scan_at({0.025, 0.025, 0.0}, {1.01}));
  EXPECT_NEAR(grid.log_odds({20, 0}), logit(0.7), 1e-6);
  EXPECT_NEAR(copy.log_odds({20, 0}), 2 * logit(0.7), 1e-5);
  OccupancyGrid moved = std::move(copy);
  moved.insert(scan_at({0.025, 0.025, 0.0}, {1.01}));
  EXPECT_NEAR(moved.log_odds({20, 0}), 3 * logit(0.7), 1e-5);
}

}  // namespace
}  // namespace wm::fusion
