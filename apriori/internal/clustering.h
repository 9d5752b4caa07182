#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace wm::apriori::internal {

/// Distance between segments a0–a1 and b0–b1 [m]; 0 when they cross or touch.
double segment_distance(const Eigen::Vector2d& a0, const Eigen::Vector2d& a1, const Eigen::Vector2d& b0,
                        const Eigen::Vector2d& b1);

/// Shared budget of elementary steps (segment pairs, bounding-box tests) for clustering a whole drawing, so that a
/// hostile or huge file fails with a clear error instead of keeping the server busy for minutes.
struct WorkBudget {
  std::size_t remaining = 200'000'000;
  /// @throw FloorPlanError when the budget is spent.
  void spend(std::size_t steps);
};

/// Groups items (each a set of open polylines, closed ones repeating their first point) into objects:
///  1. two items are connected when some segment of one comes within `tolerance_m` of a segment of the other, and
///     connected items form one group (union-find; candidate pairs from a sweep over bounding boxes);
///  2. with `merge_enclosed`, a group whose bounding box lies inside the bounding box (grown by tolerance_m) of a
///     group of larger area joins the smallest such group, transitively.
/// @return the cluster index of each item; clusters are numbered 0, 1, ... in order of their first item.
/// @throw FloorPlanError when `budget` runs out.
std::vector<std::size_t> cluster_items(const std::vector<std::vector<std::vector<Eigen::Vector2d>>>& items,
                                       double tolerance_m, bool merge_enclosed, WorkBudget& budget);

}  // namespace wm::apriori::internal
