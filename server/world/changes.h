#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "server/world/as_built.h"
#include "server/world/plan_evidence.h"
#include "server/world/world_state.h"

namespace wm::world {

/// A difference between the plan and the building that a person may accept into the plan or reject.
enum class ChangeKind {
  wall_missing,         // a plan edge the rules call missing over its whole length
  wall_partly_missing,  // a stretch of a plan edge the rules call missing
  object_gone,          // a plan object the rules call gone
  object_moved,         // a not-deformable object adjusted away from its drawn pose
  new_wall,             // an observed element that belongs to no plan object
};

struct ChangeOptions {
  double min_new_wall_length_m = 0.5;     // shorter elements are clutter, not walls to draw [m]
  std::int64_t min_new_wall_support = 3;  // observations fused into it
  /// A rigid adjustment is a move to report only beyond this and beyond 2 σ of its pose [m], [rad].
  double min_move_m = 0.02;
  double min_turn_rad = 0.0087;
  /// A new wall is a change of this building only where the plan draws the building: with an end within the box
  /// around the plan's edges (as placed) grown by this much [m]. What robots map beyond it (a car park, the next
  /// building, a log replayed elsewhere) stays in the map but is not listed. Without a plan every element qualifies. <
  /// 0: no limit.
  double plan_margin_m = 10.0;
};

struct Change {
  /// What the change is about, stable while the evidence says the same thing: "missing:<edge id>",
  /// "partly_missing:<edge id>@<s0>-<s1>" (metres, two decimals), "gone:<object>", "moved:<object>", "new:<element>".
  std::string key;
  /// "c" and 12 hex digits of a hash of the key: URL-safe (object ids may hold any character) and as stable.
  std::string id;
  ChangeKind kind = ChangeKind::new_wall;
  std::string object_id;            // the plan object concerned (empty for a new wall)
  std::optional<std::size_t> edge;  // its edge, for walls missing
  std::string element_id;           // the element, for a new wall
  Eigen::Vector2d p0 = Eigen::Vector2d::Zero(), p1 = Eigen::Vector2d::Zero();  // where, in the world frame [m]
  Stretch stretch;                                                             // along the edge, for walls missing [m]
  double length_m = 0;
  /// How sure the evidence is, in [0, 1]: the share of what was seen of the edge that was seen through; for a move,
  /// 1 − exp(−d²/2σ²) of its displacement d against its σ; for a new wall, its support against 10 views.
  double confidence = 0;
  const EdgeEvidence* evidence = nullptr;  // of the edge (points into the plan report), when known
  std::optional<Displacement> moved_by;
  std::int64_t support = 0;  // new wall: observations fused into it
  std::string rule, explanation;
};

/// The changes between the plan in `state` and the building as the grid (`evidence`, may be null) and the
/// observed elements show it, in this order: verdicts in plan order, moves, new walls by element number. Refers into
/// `evidence`, which must outlive the result.
std::vector<Change> list_changes(const WorldState& state, const PlanReport* evidence, const ChangeOptions& options);

/// The id of a change of this key.
std::string change_id(const std::string& key);

/// The wire name of a kind.
const char* to_string(ChangeKind kind);

}  // namespace wm::world
