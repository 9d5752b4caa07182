#include "tools/truth/sonar.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <random>

#include "tools/truth/world_internal.h"

namespace wm::truth {
using namespace internal;

namespace {

struct Hit {
  double t = kInf;
  Vec normal = Vec::Zero();  // unit, of the surface hit
  bool diffuse = false;      // a person: echoes at any incidence
};

Hit cast(const BuiltWorld& world, const std::vector<std::size_t>& near, const std::vector<Vec>& bodies, const Vec& o,
         const Vec& dir) {
  Hit best;
  for (const auto l : near) {
    const auto& line = world.lines[l];
    const double t = ray_segment(o, dir, line.p0, line.p1);
    if (t < best.t) {
      const Vec along = (line.p1 - line.p0).normalized();
      best = {t, Vec(-along.y(), along.x()), false};
    }
  }
  for (const auto& body : bodies) {
    const Vec w = o - body;
    const double b = w.dot(dir), c = w.squaredNorm() - kPersonRadiusM * kPersonRadiusM;
    if (c <= 0 || b * b - c < 0) continue;
    const double t = -b - std::sqrt(b * b - c);
    if (t > 0 && t < best.t) best = {t, (o + t * dir - body).normalized(), true};
  }
  return best;
}

/// Whether a ray along `dir` meeting a surface with this normal sends an echo back.
bool echoes(const Hit& hit, const Vec& dir, double limit_rad) {
  return hit.diffuse || std::abs(dir.dot(hit.normal)) >= std::cos(limit_rad);
}

/// Occupied and free as the benchmark counts them.
constexpr float kOccupied = 0.65f, kFree = 0.25f;

struct Masks {
  fusion::GridGeometry region;
  std::vector<char> on_line;  // within one cell of a true line
  std::vector<char> near;     // within 0.15 m of a true line, or near a person's track
};

Masks masks_of(const BuiltWorld& world, const fusion::GridGeometry& region) {
  Masks masks{region, std::vector<char>(region.width() * region.height(), 0),
              std::vector<char>(region.width() * region.height(), 0)};
  const double res = region.resolution_m();
  const auto mark = [&](std::vector<char>& mask, const Vec& p, std::int64_t reach) {
    const auto cx = static_cast<std::int64_t>(std::floor((p.x() - region.origin_m().x()) / res));
    const auto cy = static_cast<std::int64_t>(std::floor((p.y() - region.origin_m().y()) / res));
    for (std::int64_t dy = -reach; dy <= reach; ++dy)
      for (std::int64_t dx = -reach; dx <= reach; ++dx) {
        const auto x = cx + dx, y = cy + dy;
        if (x >= 0 && y >= 0 && x < region.width() && y < region.height()) mask[y * region.width() + x] = 1;
      }
  };
  const auto along = [&](const Vec& a, const Vec& b, const auto& visit) {
    const auto n = static_cast<int>(std::ceil((b - a).norm() / (res / 2))) + 1;
    for (int k = 0; k <= n; ++k) visit(a + (b - a) * (static_cast<double>(k) / n));
  };
  for (const auto& line : world.lines) {
    along(line.p0, line.p1, [&](const Vec& p) {
      mark(masks.on_line, p, 1);
      mark(masks.near, p, 3);
    });
  }
  for (const auto& person : world.people)
    along(person.a, person.b, [&](const Vec& p) { mark(masks.near, p, static_cast<std::int64_t>(0.45 / res)); });
  return masks;
}

GridWallScore score(const std::vector<float>& grid, const std::vector<float>& laser, const Masks& masks) {
  GridWallScore s;
  for (std::size_t i = 0; i < grid.size(); ++i) {
    const bool occupied = grid[i] > kOccupied;
    if (masks.on_line[i] && laser[i] > kOccupied) {
      ++s.wall_cells;
      if (occupied) ++s.walls_kept;
    }
    if (occupied && !masks.near[i]) ++s.false_cells;
    if (grid[i] < kFree) ++s.free_cells;
  }
  return s;
}

}  // namespace

std::vector<SonarRing> sonar_drive(const BuiltWorld& world, const Drive& drive, const LaserOptions& laser,
                                   const SonarOptions& options, unsigned seed) {
  std::mt19937 rng(seed * 7919u + 3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double limit = options.specular_limit_deg * kDeg;
  const double half = options.beam_width_deg * kDeg / 2;
  const int rays = std::max(1, static_cast<int>(std::round(options.beam_width_deg / options.ray_step_deg)));
  const double dt = laser.step_m / laser.robot_speed_mps;
  std::vector<SonarRing> rings;
  std::vector<std::size_t> near;
  for (std::size_t s = 0; s < drive.truth.size(); ++s) {
    const auto& pose = drive.truth[s];
    const Vec o(pose.x_m, pose.y_m);
    near.clear();
    for (std::size_t l = 0; l < world.lines.size(); ++l)
      if (point_segment_distance(o, world.lines[l].p0, world.lines[l].p1) < 2 * options.range_max_m) near.push_back(l);
    std::vector<Vec> bodies;
    for (const auto& person : world.people) bodies.push_back(person.at(static_cast<double>(s) * dt));
    SonarRing ring;
    ring.scan.sensor_pose = drive.scans[s].sensor_pose;
    ring.scan.beam_width_rad = 2 * half;
    ring.scan.range_min_m = options.range_min_m;
    ring.scan.range_max_m = options.range_max_m;
    ring.scan.sigma_range_m = options.sigma_range_m;
    for (int k = 0; k < options.transducers; ++k) {
      const double axis = 2 * std::numbers::pi * k / options.transducers;
      ring.scan.angles_rad.push_back(axis);
      // The first echo within the cone.
      double reading = kInf;
      for (int r = 0; r <= rays; ++r) {
        const double a = pose.theta_rad + axis - half + 2 * half * r / rays;
        const Vec dir(std::cos(a), std::sin(a));
        const auto hit = cast(world, near, bodies, o, dir);
        if (hit.t < options.range_max_m && echoes(hit, dir, limit)) reading = std::min(reading, hit.t);
      }
      auto kind = SonarTruth::echo;
      if (!std::isfinite(reading)) {
        // Specular: the axis ray bounces once; the echo comes back along the same path or not at all.
        const Vec dir(std::cos(pose.theta_rad + axis), std::sin(pose.theta_rad + axis));
        const auto first = cast(world, near, bodies, o, dir);
        kind = SonarTruth::specular_lost;
        if (first.t < options.range_max_m) {
          const Vec p = o + first.t * dir;
          const Vec mirrored = dir - 2 * dir.dot(first.normal) * first.normal;
          const auto second = cast(world, near, bodies, p + 1e-6 * mirrored, mirrored);
          if (first.t + second.t < options.range_max_m && echoes(second, mirrored, limit)) {
            reading = first.t + second.t;
            kind = SonarTruth::specular_long;
          }
        }
      }
      if (std::isfinite(reading)) reading += gauss(rng) * (options.sigma_range_m + options.sigma_per_range * reading);
      if (unit(rng) < options.cross_talk) {
        const double upper = std::isfinite(reading) ? reading : options.range_max_m;
        if (upper > options.range_min_m + 0.2) {
          reading = options.range_min_m + unit(rng) * (upper - 0.1 - options.range_min_m);
          kind = SonarTruth::cross_talk;
        }
      }
      ring.scan.ranges_m.push_back(std::isfinite(reading) ? std::max(reading, options.range_min_m)
                                                          : options.range_max_m);
      ring.kind.push_back(kind);
    }
    rings.push_back(std::move(ring));
  }
  return rings;
}

SonarFusionResult run_sonar_fusion(const std::string& name, const std::filesystem::path& data_dir, unsigned seed,
                                   double max_route_m, const SonarOptions& sonar) {
  const auto building = load_building(name, data_dir, seed, max_route_m);
  const auto world = build_world(building, Edits{}, seed);
  const LaserOptions laser_options;
  const auto laser = drive(building, world, laser_options, seed);
  const auto rings = sonar_drive(world, laser, laser_options, sonar, seed);
  fusion::LaserSonarOptions gated_options, ungated_options;
  ungated_options.gate_sonar = false;
  fusion::LaserSonarGrids gated(fusion::GridOptions{}, gated_options), ungated(fusion::GridOptions{}, ungated_options);
  SonarFusionResult result;
  result.building = name;
  for (std::size_t s = 0; s < laser.scans.size(); ++s) {
    gated.insert(laser.scans[s]);
    ungated.insert(laser.scans[s]);
    const auto verdicts = gated.insert(rings[s].scan);
    ungated.insert(rings[s].scan);
    for (std::size_t k = 0; k < rings[s].kind.size(); ++k) {
      const auto kind = rings[s].kind[k];
      ++result.readings;
      result.specular += kind == SonarTruth::specular_long || kind == SonarTruth::specular_lost;
      result.cross_talk += kind == SonarTruth::cross_talk;
      const bool dropped = verdicts.verdicts[k] == fusion::SonarVerdict::phantom;
      result.cross_talk_dropped += kind == SonarTruth::cross_talk && dropped;
      result.cross_talk_clipped +=
          kind == SonarTruth::cross_talk && verdicts.verdicts[k] == fusion::SonarVerdict::clipped;
      result.cross_talk_kept +=
          kind == SonarTruth::cross_talk && (verdicts.verdicts[k] == fusion::SonarVerdict::kept ||
                                             verdicts.verdicts[k] == fusion::SonarVerdict::unjudged);
      result.echoes_dropped += kind == SonarTruth::echo && dropped;
    }
  }
  result.scans = laser.scans.size();
  result.gate = gated.gate_counts();
  const auto bounds = gated.laser_only().bounds();
  if (!bounds) return result;
  const auto masks = masks_of(world, *bounds);
  const auto laser_layer = gated.export_layer(fusion::GridLayer::laser_bayes, *bounds);
  result.laser_only = score(laser_layer, laser_layer, masks);
  result.gated = score(gated.export_layer(fusion::GridLayer::bayes, *bounds), laser_layer, masks);
  result.ungated = score(ungated.export_layer(fusion::GridLayer::bayes, *bounds), laser_layer, masks);
  return result;
}

std::string format_sonar_table(const std::vector<SonarFusionResult>& results) {
  std::string out =
      "| building | scans | sonar readings (specular, cross talk) | gate: phantom / clipped / unjudged / kept | cross "
      "talk dropped / clipped / kept | true echoes dropped | walls kept: laser-only / gated / ungated | false occupied "
      "cells: "
      "laser-only / gated / ungated |\n|---|---|---|---|---|---|---|---|\n";
  char line[512];
  for (const auto& r : results) {
    std::snprintf(
        line, sizeof line,
        "| %s | %zu | %zu (%zu, %zu) | %llu / %llu / %llu / %llu | %zu / %zu / %zu of %zu | %zu | %.3f / %.3f / %.3f | "
        "%zu / %zu / %zu |\n",
        r.building.c_str(), r.scans, r.readings, r.specular, r.cross_talk,
        static_cast<unsigned long long>(r.gate.phantom), static_cast<unsigned long long>(r.gate.clipped),
        static_cast<unsigned long long>(r.gate.unjudged), static_cast<unsigned long long>(r.gate.kept),
        r.cross_talk_dropped, r.cross_talk_clipped, r.cross_talk_kept, r.cross_talk, r.echoes_dropped,
        r.laser_only.kept_share(), r.gated.kept_share(), r.ungated.kept_share(), r.laser_only.false_cells,
        r.gated.false_cells, r.ungated.false_cells);
    out += line;
  }
  return out;
}

}  // namespace wm::truth
