#include "apriori/internal/clustering.h"

#include <algorithm>
#include <limits>
#include <numeric>

#include "apriori/floor_plan.h"

namespace wm::apriori::internal {
namespace {

struct Box {
  Eigen::Vector2d min{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  Eigen::Vector2d max{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};

  void add(const Eigen::Vector2d& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  void add(const Box& b) {
    min = min.cwiseMin(b.min);
    max = max.cwiseMax(b.max);
  }
  bool near(const Box& b, double tol) const {
    return min.x() <= b.max.x() + tol && b.min.x() <= max.x() + tol && min.y() <= b.max.y() + tol &&
           b.min.y() <= max.y() + tol;
  }
  bool contains(const Box& b, double tol) const {
    return min.x() - tol <= b.min.x() && min.y() - tol <= b.min.y() && max.x() + tol >= b.max.x() &&
           max.y() + tol >= b.max.y();
  }
  double area() const { return (max.x() - min.x()) * (max.y() - min.y()); }
};

double cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

double point_segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = b - a;
  const double l2 = d.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((p - a).dot(d) / l2, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), std::size_t{0}); }
  std::size_t find(std::size_t i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void unite(std::size_t a, std::size_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<std::size_t> parent_;
};

using Polylines = std::vector<std::vector<Eigen::Vector2d>>;

bool items_near(const Polylines& a, const Polylines& b, const Box& box_b, double tol, WorkBudget& budget) {
  for (const auto& pa : a) {
    for (std::size_t i = 0; i + 1 < pa.size(); ++i) {
      Box sa;
      sa.add(pa[i]);
      sa.add(pa[i + 1]);
      budget.spend(1);
      if (!sa.near(box_b, tol)) continue;
      for (const auto& pb : b) {
        budget.spend(pb.size());
        for (std::size_t j = 0; j + 1 < pb.size(); ++j)
          if (segment_distance(pa[i], pa[i + 1], pb[j], pb[j + 1]) <= tol) return true;
      }
    }
  }
  // Single points (a polyline of one point) never occur: callers pass shapes with at least one edge.
  return false;
}

}  // namespace

void WorkBudget::spend(std::size_t steps) {
  if (steps > remaining)
    throw FloorPlanError("",
                         "the drawing is too complex to cluster (too many entities close together on a "
                         "clustered layer); map that layer without \"cluster\"");
  remaining -= steps;
}

double segment_distance(const Eigen::Vector2d& a0, const Eigen::Vector2d& a1, const Eigen::Vector2d& b0,
                        const Eigen::Vector2d& b1) {
  const double d1 = cross(b0, b1, a0), d2 = cross(b0, b1, a1), d3 = cross(a0, a1, b0), d4 = cross(a0, a1, b1);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return 0.0;
  return std::min({point_segment_distance(a0, b0, b1), point_segment_distance(a1, b0, b1),
                   point_segment_distance(b0, a0, a1), point_segment_distance(b1, a0, a1)});
}

std::vector<std::size_t> cluster_items(const std::vector<Polylines>& items, double tol, bool merge_enclosed,
                                       WorkBudget& budget) {
  const std::size_t n = items.size();
  std::vector<Box> boxes(n);
  for (std::size_t i = 0; i < n; ++i)
    for (const auto& line : items[i])
      for (const auto& p : line) boxes[i].add(p);

  // 1. Connectivity: sweep over the boxes sorted by min x; only pairs whose grown boxes overlap are tested.
  UnionFind uf(n);
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return boxes[a].min.x() < boxes[b].min.x(); });
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = order[k];
    for (std::size_t m = k + 1; m < n && boxes[order[m]].min.x() <= boxes[i].max.x() + tol; ++m) {
      const std::size_t j = order[m];
      budget.spend(1);
      if (!boxes[i].near(boxes[j], tol) || uf.find(i) == uf.find(j)) continue;
      if (items_near(items[i], items[j], boxes[j], tol, budget)) uf.unite(i, j);
    }
  }

  // Groups, numbered by first item.
  std::vector<std::size_t> group_of(n);
  std::vector<std::size_t> root_group(n, n);
  std::vector<Box> group_box;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t r = uf.find(i);
    if (root_group[r] == n) {
      root_group[r] = group_box.size();
      group_box.emplace_back();
    }
    group_of[i] = root_group[r];
    group_box[group_of[i]].add(boxes[i]);
  }
  const std::size_t groups = group_box.size();

  // 2. Enclosure: each group points to the smallest strictly larger group whose grown box contains it.
  std::vector<std::size_t> parent(groups, groups);
  if (merge_enclosed && groups > 1) {
    std::vector<std::size_t> by_area(groups);
    std::iota(by_area.begin(), by_area.end(), std::size_t{0});
    std::stable_sort(by_area.begin(), by_area.end(),
                     [&](std::size_t a, std::size_t b) { return group_box[a].area() < group_box[b].area(); });
    for (std::size_t a = 0; a < groups; ++a) {
      const double area_a = group_box[a].area();
      // Candidates have a larger area: start at the first group in by_area with area > area_a.
      auto first = std::upper_bound(by_area.begin(), by_area.end(), area_a,
                                    [&](double v, std::size_t g) { return v < group_box[g].area(); });
      budget.spend(1 + static_cast<std::size_t>(by_area.end() - first));
      for (auto it = first; it != by_area.end(); ++it) {
        if (group_box[*it].contains(group_box[a], tol)) {
          parent[a] = *it;  // the first container in ascending area is the smallest
          break;
        }
      }
    }
  }
  std::vector<std::size_t> root(groups);
  for (std::size_t g = 0; g < groups; ++g) {
    std::size_t r = g;
    while (parent[r] != groups) r = parent[r];  // areas strictly increase along the chain: it ends
    root[g] = r;
  }
  // Renumber clusters by first item.
  std::vector<std::size_t> number(groups, groups);
  std::size_t next = 0;
  std::vector<std::size_t> result(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t r = root[group_of[i]];
    if (number[r] == groups) number[r] = next++;
    result[i] = number[r];
  }
  return result;
}

}  // namespace wm::apriori::internal
