#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <queue>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "tools/truth/world.h"
#include "tools/truth/world_internal.h"

// A route through a building's free space when its data brings none.
namespace wm::truth {
using namespace internal;

Polyline auto_route(const std::vector<PlanWall>& walls, unsigned seed) {
  constexpr double kCell = 0.25, kClearance = 0.5, kTargetSpacing = 4.0;
  Vec lo = Vec::Constant(kInf), hi = Vec::Constant(-kInf);
  for (const auto& w : walls) {
    lo = lo.cwiseMin(w.p0).cwiseMin(w.p1);
    hi = hi.cwiseMax(w.p0).cwiseMax(w.p1);
  }
  lo -= Vec::Constant(1.0);
  hi += Vec::Constant(1.0);
  const int nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / kCell)),
            ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / kCell));
  const auto centre = [&](int i) { return Vec(lo.x() + (i % nx + 0.5) * kCell, lo.y() + (i / nx + 0.5) * kCell); };
  // Clearance, capped at 1 m: each wall marks the cells within 1 m of it.
  std::vector<double> clearance(static_cast<std::size_t>(nx) * ny, 1.0);
  for (const auto& w : walls) {
    const Vec a = w.p0.cwiseMin(w.p1) - lo - Vec::Constant(1.0), b = w.p0.cwiseMax(w.p1) - lo + Vec::Constant(1.0);
    for (int y = std::max(0, static_cast<int>(a.y() / kCell)); y < std::min(ny, static_cast<int>(b.y() / kCell) + 1);
         ++y)
      for (int x = std::max(0, static_cast<int>(a.x() / kCell)); x < std::min(nx, static_cast<int>(b.x() / kCell) + 1);
           ++x) {
        const int i = y * nx + x;
        clearance[i] = std::min(clearance[i], point_segment_distance(centre(i), w.p0, w.p1));
      }
  }
  // Free and inside; the inside test (8 rays against every wall) once per 2 × 2 cells.
  std::vector<char> free(clearance.size(), 0);
  for (int y = 0; y < ny; y += 2)
    for (int x = 0; x < nx; x += 2) {
      bool any = false;
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx)
          if (y + dy < ny && x + dx < nx) any = any || clearance[(y + dy) * nx + x + dx] >= kClearance;
      if (!any || !inside(walls, centre(y * nx + x))) continue;
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx)
          if (y + dy < ny && x + dx < nx && clearance[(y + dy) * nx + x + dx] >= kClearance)
            free[(y + dy) * nx + x + dx] = 1;
    }
  const auto neighbours = [&](int i, auto&& visit) {
    const int x = i % nx, y = i / nx;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if ((dx == 0 && dy == 0) || x + dx < 0 || x + dx >= nx || y + dy < 0 || y + dy >= ny) continue;
        const int j = (y + dy) * nx + x + dx;
        if (free[j]) visit(j, (dx != 0 && dy != 0) ? std::numbers::sqrt2 : 1.0);
      }
  };
  // The largest connected part.
  std::vector<int> part(free.size(), -1);
  int best_part = -1;
  std::size_t best_size = 0;
  for (int i = 0; i < static_cast<int>(free.size()); ++i) {
    if (!free[i] || part[i] >= 0) continue;
    std::vector<int> stack{i};
    part[i] = i;
    std::size_t size = 0;
    while (!stack.empty()) {
      const int c = stack.back();
      stack.pop_back();
      ++size;
      neighbours(c, [&](int j, double) {
        if (part[j] < 0) {
          part[j] = i;
          stack.push_back(j);
        }
      });
    }
    if (size > best_size) {
      best_size = size;
      best_part = i;
    }
  }
  if (best_part < 0) throw std::runtime_error("no free space inside the building for a route");
  for (std::size_t i = 0; i < free.size(); ++i) free[i] = free[i] && part[i] == best_part;
  // Targets: cells at least kTargetSpacing apart, in a seeded order.
  std::vector<int> cells;
  for (int i = 0; i < static_cast<int>(free.size()); ++i)
    if (free[i]) cells.push_back(i);
  std::mt19937 rng(seed);
  std::shuffle(cells.begin(), cells.end(), rng);
  std::vector<int> targets;
  // A small building (fewer than 10 targets) gets them closer, so that the drive sees its rooms from inside.
  for (const double spacing : {kTargetSpacing, kTargetSpacing / 1.6}) {
    targets.clear();
    for (const int c : cells) {
      bool far = true;
      for (const int t : targets) far = far && (centre(c) - centre(t)).norm() >= spacing;
      if (far) targets.push_back(c);
    }
    if (targets.size() >= 10) break;
  }
  // Nearest unvisited target by path length, on paths that cost more within 1 m of a wall (they keep to the middle
  // of corridors and doorways).
  std::vector<char> visited(targets.size(), 0);
  std::vector<int> order_path;
  int current = targets.front();
  visited[0] = 1;
  order_path.push_back(current);
  std::vector<double> cost(free.size());
  std::vector<int> previous(free.size());
  for (std::size_t leg = 1; leg < targets.size(); ++leg) {
    std::fill(cost.begin(), cost.end(), kInf);
    std::fill(previous.begin(), previous.end(), -1);
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    cost[current] = 0;
    queue.push({0, current});
    while (!queue.empty()) {
      // Plain variables, not a structured binding: the lambda below captures them.
      const double c = queue.top().first;
      const int i = queue.top().second;
      queue.pop();
      if (c > cost[i]) continue;
      neighbours(i, [&](int j, double step) {
        const double next = c + step * (1 + 4 * (1.0 - clearance[j]));
        if (next < cost[j]) {
          cost[j] = next;
          previous[j] = i;
          queue.push({next, j});
        }
      });
    }
    std::size_t nearest = targets.size();
    for (std::size_t t = 0; t < targets.size(); ++t)
      if (!visited[t] && (nearest == targets.size() || cost[targets[t]] < cost[targets[nearest]])) nearest = t;
    if (nearest == targets.size() || !std::isfinite(cost[targets[nearest]])) break;
    visited[nearest] = 1;
    std::vector<int> path;
    for (int i = targets[nearest]; i != current; i = previous[i]) path.push_back(i);
    order_path.insert(order_path.end(), path.rbegin(), path.rend());
    current = targets[nearest];
  }
  // Straight runs that stay in free cells.
  const auto clear_run = [&](const Vec& a, const Vec& b) {
    const int n = static_cast<int>((b - a).norm() / 0.1) + 1;
    for (int k = 0; k <= n; ++k) {
      const Vec p = a + (b - a) * (static_cast<double>(k) / n) - lo;
      const int x = static_cast<int>(p.x() / kCell), y = static_cast<int>(p.y() / kCell);
      if (x < 0 || y < 0 || x >= nx || y >= ny || !free[y * nx + x]) return false;
    }
    return true;
  };
  Polyline route{centre(order_path.front())};
  std::size_t from = 0;
  while (from + 1 < order_path.size()) {
    std::size_t to = from + 1;
    while (to + 1 < order_path.size() && clear_run(centre(order_path[from]), centre(order_path[to + 1]))) ++to;
    route.push_back(centre(order_path[to]));
    from = to;
  }
  return route;
}

}  // namespace wm::truth
