#include "tools/truth/world.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <queue>
#include <random>
#include <sstream>
#include <stdexcept>

#include "apriori/import/amrl_import.h"
#include "apriori/import/dxf_import.h"
#include "apriori/import/rmf_import.h"
#include "tools/raycast/raycast.h"

namespace wm::truth {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kDeg = std::numbers::pi / 180;

double cross(const Vec& a, const Vec& b) { return a.x() * b.y() - a.y() * b.x(); }

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// Distance along the ray to the segment; +inf when it misses.
double ray_segment(const Vec& origin, const Vec& dir, const Vec& a, const Vec& b) {
  const Vec e = b - a;
  const double denom = cross(dir, e);
  if (std::abs(denom) < 1e-12) return kInf;
  const Vec w = a - origin;
  const double t = cross(w, e) / denom;
  const double u = cross(w, dir) / denom;
  return t > 1e-9 && u >= 0 && u <= 1 ? t : kInf;
}

/// Distance along the ray to the disc; +inf when it misses or the origin is inside it.
double ray_disc(const Vec& origin, const Vec& dir, const Vec& centre, double radius) {
  const Vec w = origin - centre;
  const double c = w.squaredNorm() - radius * radius;
  if (c <= 0) return kInf;
  const double b = w.dot(dir), disc = b * b - c;
  if (disc < 0) return kInf;
  const double t = -b - std::sqrt(disc);
  return t > 0 ? t : kInf;
}

/// Inside the building: at least 6 of 8 rays hit a wall within 40 m (doorways and the open sides of a pavilion let
/// some through; from outside, at most half of them meet the building).
bool inside(const std::vector<PlanWall>& walls, const Vec& p) {
  int hits = 0;
  for (int k = 0; k < 8; ++k) {
    const Vec dir(std::cos(k * std::numbers::pi / 4 + 0.1), std::sin(k * std::numbers::pi / 4 + 0.1));
    for (const auto& w : walls)
      if (ray_segment(p, dir, w.p0, w.p1) < 40) {
        ++hits;
        break;
      }
    if (hits + (7 - k) < 6) return false;
  }
  return hits >= 6;
}

double route_distance(const std::vector<Polyline>& route, const Vec& a, const Vec& b) {
  double best = kInf;
  for (const auto& line : route)
    for (std::size_t k = 0; k + 1 < line.size(); ++k)
      best = std::min(best, segment_distance(a, b, line[k], line[k + 1]));
  return best;
}

/// Points every `step_m` along the route with their heading [m, rad].
std::vector<fusion::Pose2D> route_poses(const std::vector<Polyline>& route, double step_m) {
  std::vector<fusion::Pose2D> poses;
  for (const auto& line : route)
    for (std::size_t k = 0; k + 1 < line.size(); ++k) {
      const Vec a = line[k], b = line[k + 1];
      const double length = (b - a).norm();
      if (length < 1e-6) continue;
      const int steps = std::max(1, static_cast<int>(std::round(length / step_m)));
      const double heading = std::atan2((b - a).y(), (b - a).x());
      for (int s = 0; s < steps; ++s) {
        const Vec p = a + (b - a) * (static_cast<double>(s) / steps);
        poses.push_back({p.x(), p.y(), heading});
      }
    }
  return poses;
}

std::vector<Polyline> truncate_route(const std::vector<Polyline>& route, double max_m) {
  if (max_m <= 0) return route;
  std::vector<Polyline> kept;
  double left = max_m;
  for (const auto& line : route) {
    if (left <= 0) break;
    Polyline part{line.front()};
    for (std::size_t k = 0; k + 1 < line.size() && left > 0; ++k) {
      const double length = (line[k + 1] - line[k]).norm();
      if (length <= left) {
        part.push_back(line[k + 1]);
        left -= length;
      } else {
        part.push_back(line[k] + (line[k + 1] - line[k]) * (left / length));
        left = 0;
      }
    }
    if (part.size() >= 2) kept.push_back(std::move(part));
  }
  return kept;
}

apriori::ImportResult import_building(const std::string& name, const std::filesystem::path& data_dir) {
  if (name == "gdc1" || name == "ahg2") {
    const auto file = data_dir / "amrl-vectormaps" / (name == "gdc1" ? "GDC1.vectormap.json" : "AHG2.vectormap.json");
    return apriori::import_amrl_vectormap(read_text(file));
  }
  if (name == "rmf-office")
    return apriori::import_rmf_building(read_text(data_dir / "rmf-office" / "office.building.yaml"));
  if (name == "barcelona")
    return apriori::import_dxf(read_text(data_dir / "barcelona-pavilion" / "plan.dxf"),
                               apriori::default_layer_mapping());
  throw std::runtime_error("unknown building " + name + " (gdc1, ahg2, rmf-office, barcelona)");
}

/// The table beside the route: 1–2.1 m to its side, along it, clear of walls and route by 0.7 m, so that a shift of
/// up to 0.5 m leaves it clear of both.
fusion::Pose2D place_table(const std::vector<PlanWall>& walls, const std::vector<Polyline>& route, std::mt19937& rng) {
  auto poses = route_poses(route, 0.5);
  std::shuffle(poses.begin(), poses.end(), rng);
  for (const auto& pose : poses)
    for (const double offset : {1.0, 1.3, 1.7, 2.1})
      for (const double side : {1.0, -1.0}) {
        const Vec normal(-std::sin(pose.theta_rad), std::cos(pose.theta_rad));
        const Vec centre = Vec(pose.x_m, pose.y_m) + side * offset * normal;
        const fusion::Pose2D table{centre.x(), centre.y(), pose.theta_rad};
        bool clear = inside(walls, centre);
        for (const auto& [a, b] : table_sides(table)) {
          if (!clear) break;
          for (const auto& w : walls) clear = clear && segment_distance(a, b, w.p0, w.p1) >= 0.7;
          clear = clear && route_distance(route, a, b) >= 0.7;
        }
        if (clear) return table;
      }
  throw std::runtime_error("no place for the table beside the route");
}

}  // namespace

double point_segment_distance(const Vec& p, const Vec& a, const Vec& b) {
  const Vec e = b - a;
  const double l2 = e.squaredNorm();
  const double t = l2 > 0 ? std::clamp((p - a).dot(e) / l2, 0.0, 1.0) : 0.0;
  return (a + t * e - p).norm();
}

double segment_distance(const Vec& a0, const Vec& a1, const Vec& b0, const Vec& b1) {
  const Vec ea = a1 - a0, eb = b1 - b0;
  const double d0 = cross(ea, b0 - a0), d1 = cross(ea, b1 - a0), d2 = cross(eb, a0 - b0), d3 = cross(eb, a1 - b0);
  if (((d0 > 0) != (d1 > 0)) && ((d2 > 0) != (d3 > 0))) return 0;
  return std::min({point_segment_distance(a0, b0, b1), point_segment_distance(a1, b0, b1),
                   point_segment_distance(b0, a0, a1), point_segment_distance(b1, a0, a1)});
}

double direction_difference(const Vec& d0, const Vec& d1) {
  const double a = std::abs(std::remainder(std::atan2(d0.y(), d0.x()) - std::atan2(d1.y(), d1.x()), std::numbers::pi));
  return a;
}

std::size_t bins_of(double length_m) {
  return std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(length_m / kBinM)));
}

std::vector<std::string> building_names() { return {"gdc1", "ahg2", "rmf-office", "barcelona"}; }

std::vector<std::pair<Vec, Vec>> table_sides(const fusion::Pose2D& pose) {
  const double hx = kTableLengthM / 2, hy = kTableWidthM / 2;
  const Vec c[4] = {pose.transform_point({-hx, -hy}), pose.transform_point({hx, -hy}), pose.transform_point({hx, hy}),
                    pose.transform_point({-hx, hy})};
  return {{c[0], c[1]}, {c[1], c[2]}, {c[2], c[3]}, {c[3], c[0]}};
}

Vec Person::at(double t_s) const {
  const double length = (b - a).norm();
  if (length < 1e-9) return a;
  const double s = std::fmod(phase_m + speed_mps * t_s, 2 * length);
  if (s < length) return a + (b - a) * (s / length);
  return b - (b - a) * ((s - length) / length);
}

Building load_building(const std::string& name, const std::filesystem::path& data_dir, unsigned seed,
                       double max_route_m) {
  auto imported = import_building(name, data_dir);
  Building building;
  building.name = name;
  building.plan.name = "truth " + name;
  for (auto& object : imported.plan.objects) {
    if (!object.has_attribute("solid") || object.kind == "door") continue;
    const bool glass = object.has_attribute("glass");
    const auto edges = object.edges();
    for (std::size_t k = 0; k < edges.size(); ++k) {
      const Vec p0 = object.pose.transform_point(edges[k].p0), p1 = object.pose.transform_point(edges[k].p1);
      if ((p1 - p0).norm() < 0.01) continue;
      if (!glass) building.walls.push_back({object.id, k, p0, p1});
      building.enclosure.push_back({object.id, k, p0, p1});
    }
    if (!glass) building.plan.objects.push_back(std::move(object));
  }
  if (building.walls.empty()) throw std::runtime_error(name + ": no wall in the plan");
  if (name == "gdc1") {
    for (const auto& line : raycast::gdc1_route()) building.route.push_back(line);
  } else {
    building.route = {auto_route(building.enclosure, seed)};
  }
  building.route = truncate_route(building.route, max_route_m);
  std::mt19937 rng(seed * 7919u + 1);
  building.table = place_table(building.enclosure, building.route, rng);
  apriori::PlanObject table;
  table.id = kTableId;
  table.kind = "table";
  table.attributes = {"not_deformable"};
  table.pose = building.table;
  const double hx = kTableLengthM / 2, hy = kTableWidthM / 2;
  table.polygon = {{-hx, -hy}, {hx, -hy}, {hx, hy}, {-hx, hy}};
  building.plan.objects.push_back(std::move(table));
  return building;
}

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
      const auto [c, i] = queue.top();
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

BuiltWorld build_world(const Building& building, const Edits& edits, unsigned seed) {
  std::mt19937 rng(seed * 104729u + 3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto& walls = building.walls;
  const auto poses = route_poses(building.route, 0.5);
  if (poses.empty()) throw std::runtime_error(building.name + ": empty route");
  BuiltWorld world;

  // Demolished: walls of 1.5–5 m the route sees well (a coarse pre-pass: 1° beams every metre, 80 % of 0.25 m bins
  // hit), not near the table, each with its other face (parallel within 3°, 0.35 m away, overlapping by half).
  std::vector<std::vector<char>> coarse_hits(walls.size());
  for (std::size_t w = 0; w < walls.size(); ++w)
    coarse_hits[w].assign(std::max<std::size_t>(1, static_cast<std::size_t>((walls[w].p1 - walls[w].p0).norm() / 0.25)),
                          0);
  const auto table_now = table_sides(building.table);
  for (std::size_t k = 0; k < poses.size(); k += 2) {
    const Vec o(poses[k].x_m, poses[k].y_m);
    std::vector<std::size_t> near;
    for (std::size_t w = 0; w < walls.size(); ++w)
      if (point_segment_distance(o, walls[w].p0, walls[w].p1) < 12) near.push_back(w);
    for (int b = 0; b < 360; ++b) {
      const Vec dir(std::cos(b * kDeg), std::sin(b * kDeg));
      double best = 12;
      std::size_t hit = walls.size();
      for (const auto w : near) {
        const double t = ray_segment(o, dir, walls[w].p0, walls[w].p1);
        if (t < best) {
          best = t;
          hit = w;
        }
      }
      for (const auto& [a, c] : table_now) best = std::min(best, ray_segment(o, dir, a, c));
      if (hit == walls.size() || ray_segment(o, dir, walls[hit].p0, walls[hit].p1) > best) continue;
      const double u = (o + best * dir - walls[hit].p0).norm();
      auto& bins = coarse_hits[hit];
      bins[std::min(bins.size() - 1, static_cast<std::size_t>(u / 0.25))] = 1;
    }
  }
  const auto twins_of = [&](std::size_t w) {
    std::vector<int> group{static_cast<int>(w)};
    const Vec d = (walls[w].p1 - walls[w].p0).normalized(), n(-d.y(), d.x());
    const double length = (walls[w].p1 - walls[w].p0).norm();
    for (std::size_t v = 0; v < walls.size(); ++v) {
      if (v == w) continue;
      const Vec e = walls[v].p1 - walls[v].p0;
      if (direction_difference(d, e) > 3 * kDeg) continue;
      const Vec mid = (walls[v].p0 + walls[v].p1) / 2;
      if (std::abs(n.dot(mid - walls[w].p0)) > 0.35) continue;
      const double t0 = d.dot(walls[v].p0 - walls[w].p0), t1 = d.dot(walls[v].p1 - walls[w].p0);
      const double overlap = std::min(length, std::max(t0, t1)) - std::max(0.0, std::min(t0, t1));
      if (overlap >= 0.5 * std::max(length, e.norm())) group.push_back(static_cast<int>(v));
    }
    return group;
  };
  std::vector<std::size_t> candidates;
  for (std::size_t w = 0; w < walls.size(); ++w) {
    const double length = (walls[w].p1 - walls[w].p0).norm();
    if (length < 1.5 || length > 5) continue;
    const auto& bins = coarse_hits[w];
    if (std::count(bins.begin(), bins.end(), 1) < 0.8 * static_cast<double>(bins.size())) continue;
    bool near_table = false;
    for (const auto& [a, c] : table_now)
      near_table = near_table || segment_distance(a, c, walls[w].p0, walls[w].p1) < 1.5;
    if (!near_table) candidates.push_back(w);
  }
  std::shuffle(candidates.begin(), candidates.end(), rng);
  std::vector<char> removed(walls.size(), 0);
  for (const auto w : candidates) {
    if (world.demolished.size() >= edits.demolished) break;
    bool apart = true;
    for (const auto& group : world.demolished)
      for (const int v : group)
        apart = apart && segment_distance(walls[v].p0, walls[v].p1, walls[w].p0, walls[w].p1) >= 1.0;
    if (!apart) continue;
    auto group = twins_of(w);
    for (const int v : group) removed[v] = 1;
    world.demolished.push_back(std::move(group));
  }
  if (world.demolished.size() < edits.demolished)
    throw std::runtime_error(building.name + ": only " + std::to_string(world.demolished.size()) +
                             " walls to demolish that the route sees well");
  for (std::size_t w = 0; w < walls.size(); ++w)
    if (!removed[w]) world.lines.push_back({walls[w].p0, walls[w].p1, LineKind::wall, static_cast<int>(w)});

  // The table, moved or removed.
  if (!edits.table_removed) {
    const fusion::Pose2D moved{building.table.x_m + edits.table_shift.x(), building.table.y_m + edits.table_shift.y(),
                               building.table.theta_rad + edits.table_shift.z()};
    world.table = moved;
    for (const auto& [a, b] : table_sides(moved)) world.lines.push_back({a, b, LineKind::table, -1});
  }

  // Partitions: 2.5–3.5 m, 1.5–4 m beside the route, along or across the nearest wall, 0.5 m from every plan wall,
  // 0.7 m from the route and both places of the table, 1 m from each other.
  const auto& enclosure = building.enclosure;
  const auto clear_of = [&](const Vec& a, const Vec& b, double walls_m, double route_m) {
    for (const auto& w : enclosure)
      if (segment_distance(a, b, w.p0, w.p1) < walls_m) return false;
    for (const auto& [c, d] : table_now)
      if (segment_distance(a, b, c, d) < 0.7) return false;
    if (world.table)
      for (const auto& [c, d] : table_sides(*world.table))
        if (segment_distance(a, b, c, d) < 0.7) return false;
    for (const int p : world.partitions)
      if (segment_distance(a, b, world.lines[p].p0, world.lines[p].p1) < 1.0) return false;
    return route_distance(building.route, a, b) >= route_m;
  };
  for (int attempt = 0; attempt < 20000 && world.partitions.size() < edits.partitions; ++attempt) {
    const auto& pose = poses[static_cast<std::size_t>(unit(rng) * poses.size()) % poses.size()];
    const Vec normal(-std::sin(pose.theta_rad), std::cos(pose.theta_rad));
    const Vec mid = Vec(pose.x_m, pose.y_m) + (unit(rng) < 0.5 ? -1 : 1) * (1.5 + 2.5 * unit(rng)) * normal;
    std::size_t nearest = 0;
    double nearest_d = kInf;
    for (std::size_t w = 0; w < walls.size(); ++w) {
      const double d = point_segment_distance(mid, walls[w].p0, walls[w].p1);
      if (d < nearest_d) {
        nearest_d = d;
        nearest = w;
      }
    }
    Vec dir = (walls[nearest].p1 - walls[nearest].p0).normalized();
    if (unit(rng) < 0.5) dir = Vec(-dir.y(), dir.x());
    const double half = (2.5 + unit(rng)) / 2;
    const Vec a = mid - half * dir, b = mid + half * dir;
    if (!clear_of(a, b, 0.5, 0.7) || !inside(enclosure, mid)) continue;
    world.partitions.push_back(static_cast<int>(world.lines.size()));
    world.lines.push_back({a, b, LineKind::partition, -1});
  }
  if (world.partitions.size() < edits.partitions) throw std::runtime_error(building.name + ": no room for partitions");

  // People: tracks of 3–6 m within 3 m of the route, 0.45 m from every line (a body's radius and a margin).
  for (int attempt = 0; attempt < 20000 && world.people.size() < edits.people; ++attempt) {
    const auto& pose = poses[static_cast<std::size_t>(unit(rng) * poses.size()) % poses.size()];
    const double angle = 2 * std::numbers::pi * unit(rng), length = 3 + 3 * unit(rng);
    const Vec dir(std::cos(angle), std::sin(angle));
    const Vec start = Vec(pose.x_m, pose.y_m) + 3 * unit(rng) * Vec(-dir.y(), dir.x()) - unit(rng) * length * dir;
    const Vec end = start + length * dir;
    bool clear = inside(enclosure, (start + end) / 2);
    for (const auto& w : enclosure) clear = clear && segment_distance(start, end, w.p0, w.p1) >= 0.45;
    for (const auto& line : world.lines) clear = clear && segment_distance(start, end, line.p0, line.p1) >= 0.45;
    for (const auto& group : world.demolished)  // the grid sees through a demolished wall, not a person standing there
      for (const int v : group) clear = clear && segment_distance(start, end, walls[v].p0, walls[v].p1) >= 0.45;
    if (!clear) continue;
    world.people.push_back({start, end, 2 * length * unit(rng), edits.person_speed_mps});
  }
  if (world.people.size() < edits.people) throw std::runtime_error(building.name + ": no room for people");
  return world;
}

Drive drive(const Building& building, const BuiltWorld& world, const LaserOptions& options, unsigned seed) {
  std::mt19937 rng(seed * 15485863u + 5);
  std::normal_distribution<double> range_noise(0.0, options.sigma_range_m), xy_noise(0.0, options.sigma_xy_m),
      theta_noise(0.0, options.sigma_theta_rad);
  Drive result;
  for (const auto& line : building.route)
    for (std::size_t k = 0; k + 1 < line.size(); ++k) result.route_m += (line[k + 1] - line[k]).norm();
  result.truth = route_poses(building.route, options.step_m);
  auto& coverage = result.coverage;
  for (const auto& line : world.lines) coverage.hits.emplace_back(bins_of((line.p1 - line.p0).norm()), 0);
  std::vector<PlanWall> gone;  // the demolished plan walls, flattened
  for (const auto& group : world.demolished) {
    coverage.seen_through.emplace_back();
    for (const int v : group) {
      const auto& w = building.walls[v];
      coverage.seen_through.back().emplace_back(bins_of((w.p1 - w.p0).norm()), 0);
      gone.push_back(w);
    }
  }
  const int beams = static_cast<int>(std::round(options.field_of_view_deg / options.beam_step_deg));
  const double increment = options.beam_step_deg * kDeg;
  const double angle_min = options.field_of_view_deg >= 360 ? -std::numbers::pi : -options.field_of_view_deg * kDeg / 2;
  const double dt = options.step_m / options.robot_speed_mps;
  std::vector<std::size_t> near;
  for (std::size_t s = 0; s < result.truth.size(); ++s) {
    const auto& pose = result.truth[s];
    const Vec o(pose.x_m, pose.y_m);
    near.clear();
    for (std::size_t l = 0; l < world.lines.size(); ++l)
      if (point_segment_distance(o, world.lines[l].p0, world.lines[l].p1) < options.max_range_m) near.push_back(l);
    std::vector<Vec> bodies;
    for (const auto& person : world.people) bodies.push_back(person.at(static_cast<double>(s) * dt));
    fusion::LaserScan scan;
    scan.sensor_pose = {pose.x_m + xy_noise(rng), pose.y_m + xy_noise(rng), pose.theta_rad + theta_noise(rng)};
    scan.angle_min_rad = angle_min;
    scan.angle_increment_rad = increment;
    scan.range_min_m = 0.05;
    scan.range_max_m = options.max_range_m;
    scan.sigma_range_m = options.sigma_range_m;
    scan.ranges_m.reserve(beams);
    for (int i = 0; i < beams; ++i) {
      const double angle = pose.theta_rad + angle_min + increment * i;
      const Vec dir(std::cos(angle), std::sin(angle));
      double best = options.max_range_m;
      std::size_t hit = world.lines.size();
      for (const auto l : near) {
        const double t = ray_segment(o, dir, world.lines[l].p0, world.lines[l].p1);
        if (t < best) {
          best = t;
          hit = l;
        }
      }
      for (const auto& body : bodies) {
        const double t = ray_disc(o, dir, body, kPersonRadiusM);
        if (t < best) {
          best = t;
          hit = world.lines.size();  // a person: no line hit
        }
      }
      if (hit < world.lines.size()) {
        const auto& line = world.lines[hit];
        auto& bins = coverage.hits[hit];
        bins[std::min(bins.size() - 1, static_cast<std::size_t>((o + best * dir - line.p0).norm() / kBinM))] += 1;
      }
      // Demolished walls the beam went through before its return (or its full range without one).
      std::size_t g = 0;
      for (std::size_t group = 0; group < world.demolished.size(); ++group)
        for (std::size_t m = 0; m < world.demolished[group].size(); ++m, ++g) {
          const double t = ray_segment(o, dir, gone[g].p0, gone[g].p1);
          if (t >= best) continue;
          const Vec along = (gone[g].p1 - gone[g].p0).normalized();
          const double sin_incidence = std::abs(dir.x() * along.y() - dir.y() * along.x());
          if (sin_incidence < std::sin(kMinIncidenceRad) || (best - t) * sin_incidence < kMinDepthBeyondM) continue;
          auto& bins = coverage.seen_through[group][m];
          bins[std::min(bins.size() - 1, static_cast<std::size_t>((o + t * dir - gone[g].p0).norm() / kBinM))] += 1;
        }
      const bool returned = best < options.max_range_m;
      scan.ranges_m.push_back(returned ? best + range_noise(rng) : options.max_range_m);
    }
    result.scans.push_back(std::move(scan));
  }
  return result;
}

}  // namespace wm::truth
