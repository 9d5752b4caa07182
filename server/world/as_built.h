#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "server/world/plan_evidence.h"
#include "server/world/world_state.h"

namespace wm::world {

/// How a CAD object of the plan stands against what was observed.
enum class AsBuiltStatus {
  gone,            // the rules' verdict from the grid: the object is not there any more (a table taken away)
  missing,         // the rules' verdict: an edge of it is missing over its whole length (a wall demolished)
  partly_missing,  // the rules' verdict: a stretch of an edge is missing (a door cut in)
  moved,           // at least one rigid adjustment: the building differs from its drawing
  confirmed,       // observed where it is drawn (confirmations, no adjustment)
  never_observed,  // no observation has touched it
};

/// How far an adjusted object is from its drawn pose.
struct Displacement {
  double dx_m = 0, dy_m = 0;
  double dtheta_rad = 0;  // normalised to [-π, π]
  double distance_m = 0;  // hypot(dx, dy)
  double sigma_xy_m = 0;  // the larger of σx and σy of its current pose
};

struct ObjectAsBuilt {
  const ObjectState* object = nullptr;  // points into the state the report was made from
  AsBuiltStatus status = AsBuiltStatus::never_observed;
  std::optional<Displacement> moved_by;  // set when it was adjusted
  std::vector<const Verdict*> verdicts;  // the rules' verdicts on it and its edges (point into the plan report)
};

/// Where the building differs from its drawing: per CAD object confirmed / moved / never observed, and the
/// observed elements that belong to no object. Refers into the state it was made from, which must outlive it.
struct AsBuiltReport {
  std::vector<ObjectAsBuilt> objects;       // in plan order
  std::vector<const Element*> not_in_plan;  // by element number
  std::size_t confirmed = 0, moved = 0, never_observed = 0, missing = 0, partly_missing = 0, gone = 0;
};

/// The report of `state`, with the verdicts of `evidence` (nullptr: none) on the objects they name. A verdict goes
/// before adjustments and confirmations: a wall confirmed before it was demolished is missing now.
AsBuiltReport as_built_report(const WorldState& state, const PlanReport* evidence = nullptr);

/// The wire name of a status: "gone", "missing", "partly_missing", "moved", "confirmed", "never_observed".
const char* to_string(AsBuiltStatus status);

}  // namespace wm::world
