#pragma once
// Scans and plans the service's unit tests share.
#include <numbers>

#include "server/json/codec.h"
#include "server/world/world_state.h"

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

// A plan with one solid wall from (2, −1) to (2, 1), drawn `shift_m` further along x.
inline world::WorldState wall_state(double shift_m = 0) {
  apriori::FloorPlan plan;
  plan.name = "wall";
  apriori::PlanObject wall;
  wall.id = "w";
  wall.kind = "wall";
  wall.attributes = {"solid"};
  wall.polylines = {{{2 + shift_m, -1}, {2 + shift_m, 1}}};
  plan.objects = {wall};
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

}  // namespace wm::service
