#pragma once

// JSON of the robots resource (GET /api/v1/robots, the `robot` events) and of a reported pose
// (PUT /api/v1/robots/{id}/pose).
#include <nlohmann/json.hpp>
#include <optional>
#include <string_view>

#include "server/service/robot_registry.h"

namespace wm::json_codec {

/// {"id", "status", "pose": {"x", "y", "theta", "cov"?, "stamp", "received_at", "source"} | null, "first_seen",
///  "last_seen", "silent_s", "sensors": [...], "scans": {sensor: n}, "primitives", "poses",
///  "track": [[x, y, theta, received_at], ...] (oldest first)} — times in Unix seconds.
nlohmann::json robot_json(const service::RobotState& robot, const char* status, double now_unix_s);

struct ReportedPose {
  service::RobotPose pose;
  bool stopped = false;
  std::optional<nlohmann::json> telemetry;  // parse_robot_telemetry's object, when the body had one
};
/// Parses {"x", "y", "theta", "cov"?: 3×3 over (x, y, θ), "stamp"?, "state"?: "moving" | "stopped",
/// "telemetry"?: see parse_robot_telemetry}.
/// @throw CodecError (bad_request) naming the bad field: missing or non-finite numbers, |x| or |y| over 1e5 m, a
///        covariance that is not 3×3, not symmetric or with a negative variance, an unknown state.
ReportedPose parse_reported_pose(std::string_view body);

/// The telemetry a robot reports with its pose, validated: {"motors": [{"id": 0..255, "state"?: 0..255,
/// "mode"?: 0..255, "current"?: number | null, "temperature"?: number | null (|x| ≤ 1e6), "fault"?: bool,
/// "faults"?: 0..65535, "status_bits"?: 0..65535}, ...] (at most 16), "current_unit"?, "temperature_unit"?: strings
/// of at most 32 characters}. Returns it normalised (absent current/temperature null, fault false, faults 0) with
/// "fault": whether any motor reports one. @throw CodecError (bad_request) naming the field.
nlohmann::json parse_robot_telemetry(const nlohmann::json& telemetry);

/// Robot ids in URLs: 1 to 128 of [A-Za-z0-9._:-]. Scans and primitives name their robot ("source", "observer")
/// with the same rule when they are to be found under /api/v1/robots/{id}.
bool valid_robot_id(std::string_view id);

}  // namespace wm::json_codec
