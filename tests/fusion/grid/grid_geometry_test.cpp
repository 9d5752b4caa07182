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

}  // namespace
}  // namespace wm::fusion
