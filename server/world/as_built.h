#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "server/world/world_state.h"

namespace wm::world {

/// How a CAD object of the plan stands against what was observed.
enum class AsBuiltStatus {
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
  std::optional<Displacement> moved_by;  // set when status is moved
};

/// Where the building differs from its drawing: per CAD object confirmed / moved / never observed, and the
/// observed elements that belong to no object. Refers into the state it was made from, which must outlive it.
struct AsBuiltReport {
  std::vector<ObjectAsBuilt> objects;       // in plan order
  std::vector<const Element*> not_in_plan;  // by element number
  std::size_t confirmed = 0, moved = 0, never_observed = 0;
};

AsBuiltReport as_built_report(const WorldState& state);

/// The wire name of a status: "moved", "confirmed", "never_observed".
const char* to_string(AsBuiltStatus status);

}  // namespace wm::world
