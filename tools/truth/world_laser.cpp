#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "tools/truth/world.h"
#include "tools/truth/world_internal.h"

// The laser scans of a drive through the world as built, and what they saw of each line.
namespace wm::truth {
using namespace internal;

namespace {

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

}  // namespace

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
