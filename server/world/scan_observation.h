#pragma once

#include <Eigen/Core>
#include <string>
#include <variant>

#include "fusion/grid/scan.h"

namespace wm::world {

/// One range scan as the world model takes it: who took it, when, and a laser or a sonar scan with the sensor's pose
/// in the world frame. The wire codecs make it from a request body; the journal keeps it so that start-up replays it.
struct ScanObservation {
  std::string observer = "anonymous";  // the robot (or client) that took it
  double stamp_s = 0.0;                // the robot's clock [s]
  std::variant<fusion::LaserScan, fusion::SonarScan> scan;
  Eigen::Matrix3d pose_cov = Eigen::Matrix3d::Zero();  // of the sensor pose (x, y, θ); zero when not given
  const char* sensor() const { return std::holds_alternative<fusion::LaserScan>(scan) ? "laser" : "sonar"; }
};

}  // namespace wm::world
