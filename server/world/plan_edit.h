#pragma once

#include <optional>
#include <set>
#include <string>

#include "apriori/floor_plan.h"
#include "server/world/changes.h"
#include "server/world/update.h"
#include "server/world/world_state.h"

namespace wm::world {

/// The plan of `state` as drawn (its objects' drawings in plan order).
apriori::FloorPlan current_plan(const WorldState& state);

/// The drawing edited so that it says what `change` says of the building, in the drawing's own frame (through the
/// state's placement and each object's pose as it stands now):
///  - wall_missing: the edge is taken out of its object (a polyline split in two, a polygon opened); an object left
///    without edges goes;
///  - wall_partly_missing: the edge is cut over the stretch;
///  - object_gone: the object goes;
///  - object_moved: the object is drawn where it stands now;
///  - new_wall: a new `solid` wall object "<element>-wall" (made unique) is drawn along the element.
/// `added_object_id` (optional) receives the new object's id for a new wall.
/// @throw std::invalid_argument when the change does not apply to this state (an object or element it names is not
///        in it, an edge index past the object's edges).
apriori::FloorPlan plan_with_change(const WorldState& state, const Change& change,
                                    std::string* added_object_id = nullptr);

/// The state with `plan` as its new drawing, keeping what was learnt of the objects whose drawing did not change
/// (pose, covariance, confirmations, adjustments); objects whose drawing changed start again from it. Elements
/// numbered in `remove_elements` leave the map (a new wall now in the plan). One decision of `action` with
/// `rule`/`explanation`, observation `observation_seq`, names `subject` (object or element id).
/// Version bumped by one.
UpdateResult apply_plan_edit(const WorldState& current, const apriori::FloorPlan& plan, const WorldOptions& options,
                             const std::vector<std::int64_t>& remove_elements, std::int64_t observation_seq,
                             rules::Action action, const std::string& rule, const std::string& explanation,
                             const std::string& observer, const std::string& subject);

/// The ids of the objects of `before` that `after` does not have (a new plan, an accepted change, an undo).
std::set<std::string> removed_objects(const WorldState& before, const WorldState& after);

}  // namespace wm::world
