#pragma once
// Dense laser scans for the ingest bench: a drive through any floor plan, ray-cast with a 270° scanner of 1 081
// beams 0.25° apart (a SICK TiM5xx or Hokuyo UST-10LX). The route is not drawn for a plan: the robot starts at the
// free point farthest from every line and keeps driving to a point along one of the longest free rays it sees, so
// the same code explores any plan (corridors, rooms, furniture) without being tuned to one.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "apriori/floor_plan.h"
#include "fusion/grid/scan.h"
#include "tools/raycast/raycast.h"

namespace wm::bench {

struct DenseScannerOptions {
  int beams = 1081;
  double angle_min_rad = -135.0 * std::numbers::pi / 180;  // sensor frame
  double angle_increment_rad = 0.25 * std::numbers::pi / 180;
  double range_min_m = 0.05;
  double range_max_m = 20;  // no return beyond
  double sigma_range_m = 0.01;
  double speed_m_per_scan = 0.05;  // 2 m/s at 40 Hz
  double turn_rad_per_scan = 0.2;  // turns in place at most this between two scans
  unsigned seed = 11;
};

/// Every edge of every object of a plan, in the world frame.
inline std::vector<raycast::PlanLine> plan_lines(const apriori::FloorPlan& plan) {
  std::vector<raycast::PlanLine> lines;
  for (const auto& object : plan.objects)
    for (const auto& edge : object.edges())
      lines.push_back({object.pose.transform_point(edge.p0), object.pose.transform_point(edge.p1)});
  return lines;
}

namespace internal {

inline double distance_to_segment(const Eigen::Vector2d& p, const raycast::PlanLine& l) {
  const Eigen::Vector2d e = l.p1 - l.p0;
  const double length2 = e.squaredNorm();
  const double t = length2 > 0 ? std::clamp((p - l.p0).dot(e) / length2, 0.0, 1.0) : 0.0;
  return (p - (l.p0 + t * e)).norm();
}

inline double clearance(const std::vector<raycast::PlanLine>& lines, const Eigen::Vector2d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& l : lines) best = std::min(best, distance_to_segment(p, l));
  return best;
}

// The free point on a 0.5 m lattice over the plan that is farthest from every line and enclosed (rays in 16
// directions all hit a line): inside the building, in its most open place.
inline Eigen::Vector2d start_point(const std::vector<raycast::PlanLine>& lines) {
  Eigen::Vector2d lo(std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (const auto& l : lines) {
    lo = lo.cwiseMin(l.p0).cwiseMin(l.p1);
    hi = hi.cwiseMax(l.p0).cwiseMax(l.p1);
  }
  std::vector<std::pair<double, Eigen::Vector2d>> candidates;
  for (double x = lo.x() + 0.25; x < hi.x(); x += 0.5)
    for (double y = lo.y() + 0.25; y < hi.y(); y += 0.5) candidates.push_back({clearance(lines, {x, y}), {x, y}});
  std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  const double far = (hi - lo).norm() + 1;
  for (const auto& [free_m, p] : candidates) {
    bool enclosed = true;
    for (int k = 0; k < 16 && enclosed; ++k) {
      const double a = 2 * std::numbers::pi * k / 16;
      enclosed = std::isfinite(raycast::cast_ray(lines, p, {std::cos(a), std::sin(a)}, far));
    }
    if (enclosed) return p;
  }
  throw std::runtime_error("dense drive: no enclosed free point in the plan");
}

}  // namespace internal

/// `count` scans of a drive through `lines` (scan i at time i · period), the scanner at the robot's centre looking
/// along its heading. @throw std::runtime_error for a plan without lines or without an enclosed free point.
inline std::vector<fusion::LaserScan> dense_drive(const std::vector<raycast::PlanLine>& lines, std::size_t count,
                                                  const DenseScannerOptions& options = {}) {
  if (lines.empty()) throw std::runtime_error("dense drive: a plan without lines");
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> noise(0.0, options.sigma_range_m);
  Eigen::Vector2d position = internal::start_point(lines);
  double heading = 0;
  Eigen::Vector2d goal = position;
  std::vector<fusion::LaserScan> scans;
  std::vector<raycast::PlanLine> near;  // the lines a beam can reach from here: a fraction of a large plan's
  while (scans.size() < count) {
    near.clear();
    for (const auto& l : lines)
      if (internal::distance_to_segment(position, l) < options.range_max_m) near.push_back(l);
    fusion::LaserScan scan;
    scan.sensor_pose = {position.x(), position.y(), heading};
    scan.angle_min_rad = options.angle_min_rad;
    scan.angle_increment_rad = options.angle_increment_rad;
    scan.range_min_m = options.range_min_m;
    scan.range_max_m = options.range_max_m;
    scan.sigma_range_m = options.sigma_range_m;
    scan.ranges_m.reserve(static_cast<std::size_t>(options.beams));
    for (int i = 0; i < options.beams; ++i) {
      const double a = heading + options.angle_min_rad + options.angle_increment_rad * i;
      const double r = raycast::cast_ray(near, position, {std::cos(a), std::sin(a)}, options.range_max_m);
      scan.ranges_m.push_back(std::isfinite(r) ? r + noise(rng) : options.range_max_m);
    }
    scans.push_back(std::move(scan));

    // At the goal: the next one 1 m short of a wall along one of the three longest of 72 rays all around that do
    // not lead straight back (chosen at random among them, so that two long rays do not make a shuttle).
    if ((goal - position).norm() < options.speed_m_per_scan) {
      std::vector<std::pair<double, double>> rays;  // (free range, angle)
      for (int k = 0; k < 72; ++k) {
        const double a = heading + 2 * std::numbers::pi * k / 72;
        if (std::abs(std::remainder(a - heading, 2 * std::numbers::pi)) > 0.8 * std::numbers::pi && scans.size() > 1)
          continue;
        const double r = raycast::cast_ray(near, position, {std::cos(a), std::sin(a)}, options.range_max_m);
        rays.push_back({std::isfinite(r) ? r : options.range_max_m, a});
      }
      std::sort(rays.begin(), rays.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
      const auto& [free_m, angle] = rays[std::uniform_int_distribution<std::size_t>(0, 2)(rng) % rays.size()];
      goal = position + std::max(0.0, std::min(free_m - 1.0, 15.0)) * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    }
    // Turn towards the goal, then drive to it.
    const Eigen::Vector2d to_goal = goal - position;
    if (to_goal.norm() < 1e-9) continue;
    const double turn = std::remainder(std::atan2(to_goal.y(), to_goal.x()) - heading, 2 * std::numbers::pi);
    if (std::abs(turn) > 1e-6) {
      heading += std::clamp(turn, -options.turn_rad_per_scan, options.turn_rad_per_scan);
      if (std::abs(turn) > options.turn_rad_per_scan) continue;
    }
    position += to_goal.normalized() * std::min(options.speed_m_per_scan, to_goal.norm());
  }
  return scans;
}

}  // namespace wm::bench
