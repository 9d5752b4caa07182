#include "logs/scan_body.h"

#include <cmath>

namespace wm::logs {

nlohmann::json laser_scan_body(const fusion::LaserScan& scan, const std::string& source, double stamp) {
  using nlohmann::json;
  json ranges = json::array();
  for (const double r : scan.ranges_m) ranges.push_back(std::isfinite(r) ? json(r) : json(nullptr));
  return {{"sensor", "laser"},
          {"observer", source},
          {"stamp", stamp},
          {"pose", {{"x", scan.sensor_pose.x_m}, {"y", scan.sensor_pose.y_m}, {"theta", scan.sensor_pose.theta_rad}}},
          {"angle_min", scan.angle_min_rad},
          {"angle_increment", scan.angle_increment_rad},
          {"ranges", std::move(ranges)},
          {"range_min", scan.range_min_m},
          {"range_max", scan.range_max_m},
          {"sigma_range", scan.sigma_range_m}};
}

}  // namespace wm::logs
