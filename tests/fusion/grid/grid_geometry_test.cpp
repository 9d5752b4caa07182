#include "fusion/grid/grid_geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace wm::fusion {
namespace {

TEST(GridGeometryTest, RejectsInvalidArguments) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(GridGeometry({nan, 0}, 0.05, 10, 10), std::invalid_argument);
  EXPECT_THROW(GridGeometry({0, inf}, 0.05, 10, 10), std::invalid_argument);
  EXPECT_THROW(GridGeometry({0, 0}, 0.0, 10, 10), std::invalid_argument);
  EXPECT_THROW(GridGeometry({0, 0}, -0.05, 10, 10), std::invalid_argument);
  EXPECT_THROW(GridGeometry({0, 0}, nan, 10, 10), std::invalid_argument);
  EXPECT_THROW(GridGeometry({0, 0}, 100.5, 10, 10), std::invalid_argument);
  EXPECT_THROW(GridGeometry({0, 0}, 0.05, 0, 10), std::invalid_argument);
  EXPECT_THROW(GridGeometry({0, 0}, 0.05, 10, -1), std::invalid_argument);
  EXPECT_THROW(GridGeometry({0, 0}, 0.05, 1'000'001, 10), std::invalid_argument);
  EXPECT_NO_THROW(GridGeometry({0, 0}, 100.0, 1'000'000, 1));
}

TEST(GridGeometryTest, CellOfFloorsAlsoBelowTheOrigin) {
  const GridGeometry g({-1.0, 2.0}, 0.1, 20, 30);
  EXPECT_EQ(g.cell_of({-1.0, 2.0}), (CellIndex{0, 0}));
  EXPECT_EQ(g.cell_of({-0.95, 2.05}), (CellIndex{0, 0}));
  EXPECT_EQ(g.cell_of({-1.05, 1.95}), (CellIndex{-1, -1}));
  EXPECT_EQ(g.cell_of({-3.01, 0.0}), (CellIndex{-21, -20}));
  EXPECT_EQ(g.cell_of({0.95, 4.95}), (CellIndex{19, 29}));
}

TEST(GridGeometryTest, CenterAndCellRoundTrip) {
  const GridGeometry g({-1.0, 2.0}, 0.05, 20, 30);
  for (std::int64_t x = -50; x <= 50; x += 7) {
    for (std::int64_t y = -40; y <= 60; y += 9) {
      const CellIndex c{x, y};
      EXPECT_EQ(g.cell_of(g.center_of(c)), c);
    }
  }
  const Eigen::Vector2d p(-1.234, 0.987);
  const Eigen::Vector2d center = g.center_of(g.cell_of(p));
  EXPECT_LE((center - p).cwiseAbs().maxCoeff(), 0.025 + 1e-12);
  EXPECT_NEAR(g.center_of({0, 0}).x(), -0.975, 1e-12);
  EXPECT_NEAR(g.center_of({-1, 0}).x(), -1.025, 1e-12);
}

TEST(GridGeometryTest, ContainsOnlyCellsInsideTheBounds) {
  const GridGeometry g({0, 0}, 1.0, 3, 2);
  EXPECT_TRUE(g.contains({0, 0}));
  EXPECT_TRUE(g.contains({2, 1}));
  EXPECT_FALSE(g.contains({3, 1}));
  EXPECT_FALSE(g.contains({2, 2}));
  EXPECT_FALSE(g.contains({-1, 0}));
  EXPECT_FALSE(g.contains({0, -1}));
}

TEST(GridGeometryTest, CellOfRejectsNonFiniteAndFarPoints) {
  const GridGeometry g({0, 0}, 0.05, 10, 10);
  EXPECT_THROW(g.cell_of({std::numeric_limits<double>::quiet_NaN(), 0}), std::out_of_range);
  EXPECT_THROW(g.cell_of({0, std::numeric_limits<double>::infinity()}), std::out_of_range);
  EXPECT_THROW(g.cell_of({1e300, 0}), std::out_of_range);
}

TEST(GridGeometryTest, TileOfFloorsNegativeCellsIntoNegativeTiles) {
  const auto a = tile_of({0, 63}, 64);
  EXPECT_EQ(a.tile, (TileIndex{0, 0}));
  EXPECT_EQ(a.y, 63);
  const auto b = tile_of({-1, -64}, 64);
  EXPECT_EQ(b.tile, (TileIndex{-1, -1}));
  EXPECT_EQ(b.x, 63);
  EXPECT_EQ(b.y, 0);
  const auto c = tile_of({-65, 128}, 64);
  EXPECT_EQ(c.tile, (TileIndex{-2, 2}));
  EXPECT_EQ(c.x, 63);
  EXPECT_EQ(c.y, 0);
  // Every cell of a span lands in its tile, at its place: tile·T + place gives it back.
  for (std::int64_t x = -200; x <= 200; ++x) {
    const auto t = tile_of({x, -x}, 16);
    EXPECT_EQ(t.tile.x * 16 + t.x, x);
    EXPECT_EQ(t.tile.y * 16 + t.y, -x);
    EXPECT_TRUE(t.x >= 0 && t.x < 16 && t.y >= 0 && t.y < 16);
  }
}

TEST(GridGeometryTest, CellAtIsTheLatticeAtTheWorldOrigin) {
  EXPECT_EQ(cell_at({0.0, 0.049}, 0.05), (CellIndex{0, 0}));
  EXPECT_EQ(cell_at({-0.001, 0.05}, 0.05), (CellIndex{-1, 1}));
  const GridGeometry g({0, 0}, 0.05, 1, 1);
  for (const double x : {-3.21, -0.05, 0.0, 0.07, 12.34}) EXPECT_EQ(cell_at({x, -x}, 0.05), g.cell_of({x, -x}));
  EXPECT_THROW(cell_at({std::numeric_limits<double>::quiet_NaN(), 0}, 0.05), std::out_of_range);
  EXPECT_THROW(cell_at({1e300, 0}, 0.05), std::out_of_range);
  EXPECT_THROW(cell_at({0, 0}, 0.0), std::invalid_argument);
}

TEST(GridGeometryTest, CoveringSnapsABoxOutwardsToWholeCells) {
  const auto r = covering({-0.12, 0.0}, {0.26, 0.10}, 0.05);
  EXPECT_EQ(r.first, (CellIndex{-3, 0}));
  EXPECT_EQ(r.end, (CellIndex{6, 2}));  // 0.26 / 0.05 = 5.2 up to 6; 0.10 on a border takes no cell beyond
  EXPECT_EQ(r.width(), 9);
  EXPECT_EQ(r.height(), 2);
  const auto g = r.geometry(0.05);
  EXPECT_NEAR(g.origin_m().x(), -0.15, 1e-12);
  EXPECT_NEAR(g.origin_m().y(), 0.0, 1e-12);
  EXPECT_EQ(g.width(), 9);
  EXPECT_EQ(g.height(), 2);
  EXPECT_THROW(covering({1, 0}, {0, 1}, 0.05), std::invalid_argument);
  EXPECT_THROW(covering({0, 0}, {std::numeric_limits<double>::infinity(), 1}, 0.05), std::out_of_range);
  EXPECT_THROW(covering({0, 0}, {0, 0}, 0.05).geometry(0.05), std::invalid_argument);  // no cell
}

TEST(GridGeometryTest, PoolMaxKeepsTheLargestKnownValue) {
  const float nan = std::nanf("");
  float cell = nan;
  pool_max(cell, nan);
  EXPECT_TRUE(std::isnan(cell));
  pool_max(cell, 0.3f);
  EXPECT_EQ(cell, 0.3f);
  pool_max(cell, nan);
  EXPECT_EQ(cell, 0.3f);
  pool_max(cell, 0.2f);
  EXPECT_EQ(cell, 0.3f);
  pool_max(cell, 0.9f);
  EXPECT_EQ(cell, 0.9f);
}

}  // namespace
}  // namespace wm::fusion
