#include "server/service/robot_registry.h"

#include <cmath>
#include <numbers>
#include <variant>

namespace wm::service {

const char* to_string(RobotStatus status) {
  switch (status) {
    case RobotStatus::alive:
      return "alive";
    case RobotStatus::stale:
      return "stale";
    case RobotStatus::stopped:
      return "stopped";
  }
  return "stale";
}

RobotRegistry::RobotRegistry(RobotOptions options) : options_(options) {}

RobotState& RobotRegistry::touch(const std::string& id, double received_at_unix_s) {
  auto& robot = robots_[id];
  if (robot.id.empty()) {
    robot.id = id;
    robot.first_seen_unix_s = received_at_unix_s;
  }
  robot.last_seen_unix_s = std::max(robot.last_seen_unix_s, received_at_unix_s);
  return robot;
}

void RobotRegistry::add_to_track(RobotState& robot, const RobotPose& pose) const {
  if (!robot.track.empty()) {
    const auto& last = robot.track.back();
    const double moved = std::hypot(pose.x - last.x, pose.y - last.y);
    const double turned = std::abs(std::remainder(pose.theta - last.theta, 2 * std::numbers::pi));
    if (moved < options_.track_spacing_m && turned < options_.track_spacing_rad) return;
  }
  robot.track.push_back(pose);
  while (robot.track.size() > options_.track_points) robot.track.pop_front();
}

std::optional<RobotState> RobotRegistry::due(RobotState& robot, bool status_changed) {
  auto& last = last_event_[robot.id];
  const double now = robot.last_seen_unix_s;
  if (!status_changed && last > 0 && now - last < options_.event_interval_s) return std::nullopt;
  last = now;
  return robot;
}

RobotPose scan_pose(const world::ScanObservation& scan, double received_at_unix_s) {
  const auto pose = std::visit([](const auto& s) { return s.sensor_pose; }, scan.scan);
  return RobotPose{pose.x_m,
                   pose.y_m,
                   pose.theta_rad,
                   scan.pose_cov.isZero() ? std::nullopt : std::optional<Eigen::Matrix3d>(scan.pose_cov),
                   scan.stamp_s,
                   received_at_unix_s,
                   std::string("scan:") + scan.sensor()};
}

std::optional<RobotState> RobotRegistry::on_scan(const std::string& id, const std::string& sensor, RobotPose pose) {
  std::lock_guard lock(mutex_);
  auto& robot = touch(id, pose.received_at_unix_s);
  const bool was_stopped = robot.stopped;
  robot.stopped = false;
  ++robot.scans[sensor];
  pose.via = "scan:" + sensor;
  add_to_track(robot, pose);
  robot.pose = std::move(pose);
  return due(robot, was_stopped);
}

std::optional<RobotState> RobotRegistry::on_primitives(const std::string& id, double received_at_unix_s) {
  std::lock_guard lock(mutex_);
  auto& robot = touch(id, received_at_unix_s);
  const bool was_stopped = robot.stopped;
  robot.stopped = false;
  ++robot.primitives;
  return due(robot, was_stopped);
}

std::optional<RobotState> RobotRegistry::on_pose(const std::string& id, RobotPose pose, bool stopped) {
  std::lock_guard lock(mutex_);
  auto& robot = touch(id, pose.received_at_unix_s);
  const bool changed = robot.stopped != stopped;
  robot.stopped = stopped;
  ++robot.poses;
  pose.via = "reported";
  add_to_track(robot, pose);
  robot.pose = std::move(pose);
  return due(robot, changed);
}

std::vector<RobotState> RobotRegistry::list() const {
  std::lock_guard lock(mutex_);
  std::vector<RobotState> out;
  out.reserve(robots_.size());
  for (const auto& [id, robot] : robots_) out.push_back(robot);
  return out;
}

std::optional<RobotState> RobotRegistry::find(const std::string& id) const {
  std::lock_guard lock(mutex_);
  const auto it = robots_.find(id);
  if (it == robots_.end()) return std::nullopt;
  return it->second;
}

RobotStatus RobotRegistry::status(const RobotState& robot, double now_unix_s) const {
  if (robot.stopped) return RobotStatus::stopped;
  return now_unix_s - robot.last_seen_unix_s <= options_.alive_s ? RobotStatus::alive : RobotStatus::stale;
}

void RobotRegistry::restore(RobotState robot) {
  std::lock_guard lock(mutex_);
  while (robot.track.size() > options_.track_points) robot.track.pop_front();
  robots_[robot.id] = std::move(robot);
}

}  // namespace wm::service
