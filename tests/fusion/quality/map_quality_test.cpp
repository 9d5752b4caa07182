#include "fusion/quality/map_quality.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace wm::fusion {
namespace {

// A segment from a to b (the line normalised, the extent along its direction).
LineSegment segment(Eigen::Vector2d a, Eigen::Vector2d b) {
  const Eigen::Vector2d d = (b - a).normalized();
  LineFeature line;
  line.phi_rad = std::atan2(d.x(), -d.y());  // normal = direction turned by −90°
  line.rho_m = a.dot(line.normal());
  line = line.normalized();
  LineSegment s{line, line.coordinate_along(a), line.coordinate_along(b)};
  if (s.t0_m > s.t1_m) std::swap(s.t0_m, s.t1_m);
  return s;
}

// 10 m × 10 m at 5 cm, free (P 0.1) except one occupied row (P 0.9) whose centres lie on y = 2.025.
struct Room {
  GridGeometry geometry{Eigen::Vector2d(0, 0), 0.05, 200, 200};
  std::vector<float> p = std::vector<float>(200 * 200, 0.1F);
  Room() {
    for (int x = 0; x < 200; ++x) p[40 * 200 + x] = 0.9F;
  }
};

TEST(MapQualityTest, ElementOnTheWallIsPreciseAndExplainsTheCellsItCovers) {
  const Room room;
  const std::vector<LineSegment> map{segment({1, 2.025}, {9, 2.025})};
  const auto q = map_quality(map, room.geometry, room.p);
  EXPECT_EQ(q.elements, 1U);
  EXPECT_NEAR(q.total_length_m, 8.0, 1e-9);
  EXPECT_NEAR(q.precision, 1.0, 1e-9);
  EXPECT_EQ(q.occupied_cells, 200U);
  // Cells whose centre lies within 10 cm of [1, 9]: centres 0.925 … 9.075, 164 of the row's 200.
  EXPECT_NEAR(q.recall, 164.0 / 200.0, 1e-9);
  EXPECT_DOUBLE_EQ(q.redundancy, 0.0);
  EXPECT_NEAR(q.elements_per_m, 1.0 / 8.0, 1e-12);
}

TEST(MapQualityTest, ElementInFreeSpaceIsNotPrecise) {
  const Room room;
  const std::vector<LineSegment> map{segment({1, 2.025}, {5, 2.025}), segment({1, 6}, {5, 6})};
  const auto q = map_quality(map, room.geometry, room.p);
  EXPECT_NEAR(q.precision, 0.5, 1e-9);  // one cell's reach (5 cm) around y = 6 holds no occupied cell
}

TEST(MapQualityTest, TheSameWallKeptTwiceIsRedundant) {
  const Room room;
  const auto twice =
      map_quality(std::vector<LineSegment>{segment({1, 2.025}, {9, 2.025}), segment({1, 2.055}, {9, 2.055})},
                  room.geometry, room.p);
  EXPECT_NEAR(twice.redundancy, 1.0, 1e-9);  // 3 cm apart, parallel
  const auto apart =
      map_quality(std::vector<LineSegment>{segment({1, 2.025}, {9, 2.025}), segment({1, 2.125}, {9, 2.125})},
                  room.geometry, room.p);
  EXPECT_DOUBLE_EQ(apart.redundancy, 0.0);  // 10 cm apart: two walls
  const auto crossing =
      map_quality(std::vector<LineSegment>{segment({1, 2}, {9, 2}), segment({5, 1}, {5, 3})}, room.geometry, room.p);
  EXPECT_DOUBLE_EQ(crossing.redundancy, 0.0);  // they touch, but at 90°
  // Overlapping halves: [1, 5] and [3, 9] share [3, 5] (plus the 5 cm reach at each end of the overlap).
  const auto overlap =
      map_quality(std::vector<LineSegment>{segment({1, 2.025}, {5, 2.025}), segment({3, 2.025}, {9, 2.025})},
                  room.geometry, room.p);
  EXPECT_NEAR(overlap.redundancy, 4.1 / 10.0, 0.005);
}

TEST(MapQualityTest, MedianAndEmptyMaps) {
  const Room room;
  const std::vector<LineSegment> map{segment({1, 1}, {2, 1}), segment({1, 3}, {4, 3}), segment({1, 5}, {8, 5}),
                                     segment({1, 7}, {3, 7})};
  EXPECT_NEAR(map_quality(map, room.geometry, room.p).median_length_m, 2.5, 1e-9);  // lengths 1, 2, 3, 7
  const auto empty = map_quality({}, room.geometry, room.p);
  EXPECT_EQ(empty.elements, 0U);
  EXPECT_DOUBLE_EQ(empty.precision, 0.0);
  EXPECT_DOUBLE_EQ(empty.recall, 0.0);
  EXPECT_DOUBLE_EQ(empty.elements_per_m, 0.0);
}

TEST(MapQualityTest, UnknownCellsAreNeverOccupiedAndBadInputIsRefused) {
  Room room;
  for (auto& v : room.p) v = std::numeric_limits<float>::quiet_NaN();
  const std::vector<LineSegment> map{segment({1, 2.025}, {9, 2.025})};
  const auto q = map_quality(map, room.geometry, room.p);
  EXPECT_EQ(q.occupied_cells, 0U);
  EXPECT_DOUBLE_EQ(q.precision, 0.0);
  EXPECT_THROW(map_quality(map, room.geometry, std::vector<float>(10, 0.5F)), std::invalid_argument);
  MapQualityOptions bad;
  bad.sample_step_m = 0;
  EXPECT_THROW(map_quality(map, room.geometry, room.p, bad), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
