#pragma once

// JSON of the live events (GET /api/v1/events, one object per event; the hub splices "seq" in). The service says
// what happened in world values; these say it on the wire.
#include <Eigen/Geometry>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "fusion/geometry/pose2d.h"
#include "rules/types.h"
#include "server/service/robot_registry.h"
#include "server/world/update.h"
#include "server/world/world_state.h"

namespace wm::json_codec {

/// {"type": "scan", "scan_seq", "observer", "sensor", "pose": {x, y, theta}, "grid_revision", "bbox": [x0, y0, x1, y1],
///  "points": [[x, y], ...] (to the millimetre)}: a scan went into the grid.
nlohmann::json scan_event(std::int64_t scan_seq, const std::string& observer, const std::string& sensor,
                          const fusion::Pose2D& pose, const Eigen::AlignedBox2d& changed,
                          const std::vector<Eigen::Vector2d>& points);

/// {"type": "update", "observation", "version", "origin", "decisions", "elements", "removed", "removed_objects",
///  "objects"}: what one commit changed, from the update and the state after it.
nlohmann::json update_event(std::int64_t observation_seq, const std::string& origin, const world::UpdateResult& update,
                            const std::set<std::string>& removed_objects, const world::WorldOptions& options);

/// {"type": "floorplan", "version", "name", "objects"}: a plan was loaded.
nlohmann::json floorplan_event(std::int64_t version, const std::string& name, std::size_t objects);

/// {"type": "rules", "status"}: the rule files were (re)loaded, or a reload failed.
nlohmann::json rules_event(const rules::RulesStatus& status);

/// {"type": "robot", "robot"}: a robot's pose or status, as GET /api/v1/robots/{id} gives it.
nlohmann::json robot_event(const service::RobotState& robot, const char* status, double now_unix_s);

/// {"type": "change", "change", "verdict": "accepted" | "rejected" | "undone", "version"}.
nlohmann::json change_event(const std::string& change_id, const std::string& verdict, std::int64_t version);

/// {"type": "placement", "version", "placement", "rule", "explanation"}: the plan was moved.
nlohmann::json placement_event(std::int64_t version, const fusion::Similarity2D& placement,
                               const Eigen::Matrix4d& placement_cov, const world::DecisionRecord& decision);

/// {"type": "georeference", "version"}.
nlohmann::json georeference_event(std::int64_t version);

}  // namespace wm::json_codec
