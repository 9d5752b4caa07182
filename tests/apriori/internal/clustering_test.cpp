#include "apriori/internal/clustering.h"

#include <gtest/gtest.h>

#include "apriori/floor_plan.h"

namespace wm::apriori::internal {
namespace {

using Item = std::vector<std::vector<Eigen::Vector2d>>;

Item segment(double x0, double y0, double x1, double y1) { return {{{x0, y0}, {x1, y1}}}; }
Item square(double x, double y, double size) {
  return {{{x, y}, {x + size, y}, {x + size, y + size}, {x, y + size}, {x, y}}};
}

TEST(ClusteringTest, SegmentDistanceIsZeroForCrossingAndTouchingSegments) {
  EXPECT_EQ(segment_distance({0, 0}, {2, 2}, {0, 2}, {2, 0}), 0.0);
  EXPECT_EQ(segment_distance({0, 0}, {1, 0}, {1, 0}, {1, 5}), 0.0);
  EXPECT_DOUBLE_EQ(segment_distance({0, 0}, {1, 0}, {0.5, 0.3}, {0.5, 2}), 0.3);
  EXPECT_DOUBLE_EQ(segment_distance({0, 0}, {1, 0}, {4, 4}, {5, 4}), 5.0);
  EXPECT_DOUBLE_EQ(segment_distance({0, 0}, {1, 0}, {2, 0}, {3, 0}), 1.0);  // collinear, apart
  EXPECT_EQ(segment_distance({0, 0}, {2, 0}, {1, 0}, {3, 0}), 0.0);         // collinear, overlapping
}

TEST(ClusteringTest, ItemsWithinToleranceJoinTransitively) {
  WorkBudget budget;
  const auto c = cluster_items({segment(0, 0, 1, 0), segment(5, 0, 6, 0), segment(1.01, 0, 2, 0),
                                segment(2, 0.015, 2, 1), segment(6.5, 0, 7, 0)},
                               0.02, false, budget);
  EXPECT_EQ(c, (std::vector<std::size_t>{0, 1, 0, 0, 2}));  // numbered by first item
}

TEST(ClusteringTest, EnclosedGroupsJoinTheSmallestEnclosingGroup) {
  WorkBudget budget;
  // A room (10 m), a table inside it (1 m), a button on the table (5 cm), and a chair outside.
  const std::vector<Item> items{square(0, 0, 10), square(2, 2, 1), square(2.4, 2.4, 0.05), square(20, 0, 0.5)};
  EXPECT_EQ(cluster_items(items, 0.02, true, budget), (std::vector<std::size_t>{0, 0, 0, 1}));
  EXPECT_EQ(cluster_items(items, 0.02, false, budget), (std::vector<std::size_t>{0, 1, 2, 3}));
}

TEST(ClusteringTest, RunsOutOfBudgetWithAClearError) {
  std::vector<Item> items;
  for (int i = 0; i < 200; ++i) items.push_back(square(0.001 * i, 0, 1));
  WorkBudget budget{1000};
  EXPECT_THROW(cluster_items(items, 0.02, true, budget), FloorPlanError);
}

}  // namespace
}  // namespace wm::apriori::internal
