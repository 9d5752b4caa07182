#include "tools/truth/world.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

#include "tools/truth/world_internal.h"

// The geometry of the simulated building and the world as built from the plan by the edits.
namespace wm::truth {
namespace internal {

double ray_segment(const Vec& origin, const Vec& dir, const Vec& a, const Vec& b) {
  const Vec e = b - a;
  const double denom = cross(dir, e);
  if (std::abs(denom) < 1e-12) return kInf;
  const Vec w = a - origin;
  const double t = cross(w, e) / denom;
  const double u = cross(w, dir) / denom;
  return t > 1e-9 && u >= 0 && u <= 1 ? t : kInf;
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

}  // namespace internal

using namespace internal;

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
    // A wall whose other face runs on past it (a longer face, only partly across from this one) is not taken away:
    // that edit would leave the wall standing a few cm behind where it is drawn, a thinner wall, not a missing one.
    const Vec d = (walls[w].p1 - walls[w].p0).normalized(), n(-d.y(), d.x());
    const double length = (walls[w].p1 - walls[w].p0).norm();
    bool half_a_wall = false;
    for (std::size_t v = 0; v < walls.size() && !half_a_wall; ++v) {
      if (std::find(group.begin(), group.end(), static_cast<int>(v)) != group.end()) continue;
      if (direction_difference(d, walls[v].p1 - walls[v].p0) > 3 * kDeg) continue;
      if (std::abs(n.dot((walls[v].p0 + walls[v].p1) / 2 - walls[w].p0)) > 0.35) continue;
      const double t0 = d.dot(walls[v].p0 - walls[w].p0), t1 = d.dot(walls[v].p1 - walls[w].p0);
      half_a_wall = std::min(length, std::max(t0, t1)) - std::max(0.0, std::min(t0, t1)) >= 0.3;
    }
    if (half_a_wall) continue;
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

}  // namespace wm::truth
