#pragma once

// The robots the server has heard from: where each is (its last scan's sensor pose or the pose it reported), since
// when, what it sent, and whether it is alive. In memory, restored from the journal at start.
#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "server/world/scan_observation.h"

namespace wm::service {

struct RobotOptions {
  /// A robot heard from within this many seconds is alive; later, stale (unless it said it stopped).
  double alive_s = 5.0;
  /// The recent track kept per robot: at most this many poses, at least this far apart [m] (or this much turned).
  std::size_t track_points = 200;
  double track_spacing_m = 0.05;
  double track_spacing_rad = 0.1;
  /// Robot events on the WebSocket: at most one per robot per this many seconds (a status change always goes).
  double event_interval_s = 0.2;
};

struct RobotPose {
  double x = 0, y = 0, theta = 0;
  std::optional<Eigen::Matrix3d> cov;  // over (x, y, θ); nullopt when the robot did not give one
  double stamp_s = 0;                  // the robot's clock
  double received_at_unix_s = 0;       // the server's
  std::string via;                     // how the pose came: "scan:laser", "scan:sonar" or "reported"
};

/// Where a scan says its robot is: the scan's sensor pose and covariance, "scan:<sensor>".
RobotPose scan_pose(const world::ScanObservation& scan, double received_at_unix_s);

enum class RobotStatus { alive, stale, stopped };
const char* to_string(RobotStatus status);

struct RobotState {
  std::string id;
  std::optional<RobotPose> pose;
  std::map<std::string, std::int64_t> scans;  // by sensor
  std::int64_t primitives = 0;                // primitives requests
  std::int64_t poses = 0;                     // poses reported
  double first_seen_unix_s = 0;
  double last_seen_unix_s = 0;
  bool stopped = false;         // the robot's last report said it stopped; cleared by anything it sends later
  std::deque<RobotPose> track;  // oldest first
};

class RobotRegistry {
 public:
  explicit RobotRegistry(RobotOptions options = {});

  /// Each returns the robot as it is now when an event is due for it (see RobotOptions::event_interval_s).
  std::optional<RobotState> on_scan(const std::string& id, const std::string& sensor, RobotPose pose);
  std::optional<RobotState> on_primitives(const std::string& id, double received_at_unix_s);
  std::optional<RobotState> on_pose(const std::string& id, RobotPose pose, bool stopped);

  std::vector<RobotState> list() const;  // by id
  std::optional<RobotState> find(const std::string& id) const;
  RobotStatus status(const RobotState& robot, double now_unix_s) const;
  const RobotOptions& options() const { return options_; }

  /// Puts a robot back as the journal had it (at start).
  void restore(RobotState robot);

 private:
  RobotState& touch(const std::string& id, double received_at_unix_s);
  void add_to_track(RobotState& robot, const RobotPose& pose) const;
  std::optional<RobotState> due(RobotState& robot, bool status_changed);

  RobotOptions options_;
  mutable std::mutex mutex_;
  std::map<std::string, RobotState> robots_;
  std::map<std::string, double> last_event_;  // by id, the server's clock
};

}  // namespace wm::service
