#pragma once
// Scans, observations and plans the service's unit tests share.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "server/json/codec.h"
#include "server/service/event_log.h"
#include "server/service/map_writer.h"
#include "server/storage/store.h"
#include "server/world/update.h"
#include "server/world/world_state.h"
#include "support/temp_dir.h"

namespace wm::service {

// A 360° laser scan of 720 beams from (x, 0), every beam returning at `range`.
inline world::ScanObservation ring_scan(double x, double range) {
  fusion::LaserScan scan;
  scan.sensor_pose = {x, 0, 0};
  scan.angle_min_rad = -std::numbers::pi;
  scan.angle_increment_rad = 2 * std::numbers::pi / 720;
  scan.ranges_m.assign(720, range);
  scan.range_min_m = 0.05;
  scan.range_max_m = 30;
  world::ScanObservation request;
  request.observer = "test";
  request.scan = scan;
  return request;
}

// A plan with one solid wall "w" from (2, −1) to (2, 1), drawn `shift_m` further along x.
inline apriori::FloorPlan wall_plan(double shift_m = 0) {
  apriori::FloorPlan plan;
  plan.name = "wall";
  apriori::PlanObject wall;
  wall.id = "w";
  wall.kind = "wall";
  wall.attributes = {"solid"};
  wall.polylines = {{{2 + shift_m, -1}, {2 + shift_m, 1}}};
  plan.objects = {wall};
  return plan;
}

// The map of wall_plan(shift_m).
inline world::WorldState wall_state(double shift_m = 0) {
  const auto plan = wall_plan(shift_m);
  world::WorldState state;
  state.objects = world::ObjectTable(world::make_objects(plan, world::WorldOptions{}, 1));
  return state;
}

// As ring_scan, but the beams that meet the wall of wall_state() (x = 2, y in [−1, 1]) return on it.
inline world::ScanObservation scan_of_standing_wall() {
  auto request = ring_scan(0, 5.0);
  auto& scan = std::get<fusion::LaserScan>(request.scan);
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double bearing = scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
    if (std::abs(std::tan(bearing)) < 0.5 && std::cos(bearing) > 0) scan.ranges_m[i] = 2.0 / std::cos(bearing);
  }
  return request;
}

// One line from `a` to `b` posted by robot-1, with the covariance of 1 cm noise on its ends.
inline world::Observation one_line(Eigen::Vector2d a, Eigen::Vector2d b) {
  world::Observation observation;
  observation.observer = "robot-1";
  auto s = fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
  s.line.cov = world::midpoint_line_cov(s, 0.01, 0.01);
  observation.segments.push_back({s});
  return observation;
}

// A 720-beam laser scan from (x, y), heading 0, by robot-1 (or `observer`): each beam's range is
// `range_of(cos, sin)` of its bearing.
template <typename RangeOf>
world::ScanObservation laser_scan(double x, double y, double range_max_m, RangeOf range_of,
                                  std::string observer = "robot-1") {
  fusion::LaserScan scan;
  scan.sensor_pose = {x, y, 0};
  scan.angle_min_rad = -std::numbers::pi;
  scan.angle_increment_rad = 2 * std::numbers::pi / 720;
  scan.range_min_m = 0.05;
  scan.range_max_m = range_max_m;
  for (int i = 0; i < 720; ++i) {
    const double bearing = scan.angle_min_rad + i * scan.angle_increment_rad;
    scan.ranges_m.push_back(range_of(std::cos(bearing), std::sin(bearing)));
  }
  world::ScanObservation request;
  request.observer = std::move(observer);
  request.scan = scan;
  return request;
}

// A 720-beam laser scan from (x, y) inside the room [0, 10] × [0, 8] m, every beam ending on its walls.
inline world::ScanObservation room_scan(double x, double y, std::string observer = "robot-1") {
  return laser_scan(
      x, y, 30,
      [&](double c, double s) {
        double range = 1e9;
        if (c > 1e-9) range = std::min(range, (10 - x) / c);
        if (c < -1e-9) range = std::min(range, -x / c);
        if (s > 1e-9) range = std::min(range, (8 - y) / s);
        if (s < -1e-9) range = std::min(range, -y / s);
        return range;
      },
      std::move(observer));
}

// A map writer on a fresh SQLite store with the shipped rules, and what it needs: the parts under the ingest.
struct WriterParts {
  testing::TempDir dir;
  storage::Store store{{(dir.path() / "world.db").string(), false}};
  rules::Engine engine{rules::EngineOptions{WM_SOURCE_DIR "/rules/prolog"}};
  common::Diagnostics diagnostics{"", nullptr};
  EventLog events{nullptr, diagnostics};
  MapWriter writer{MapWriterOptions{}, store.load(world::WorldOptions{}), engine, diagnostics};
};

}  // namespace wm::service
