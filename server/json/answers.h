#pragma once

// JSON of what the service answers beyond single world values (see codec.h for those): decision lists and the
// as-built report.
#include <nlohmann/json.hpp>
#include <vector>

#include "server/world/as_built.h"
#include "server/world/changes.h"
#include "server/world/update.h"

namespace wm::json_codec {

/// [decision, ...] in order, each as decision_json.
nlohmann::json decisions_json(const std::vector<world::DecisionRecord>& decisions);

/// {"plan", "version", "grid_revision", "summary": {"objects", "confirmed", "moved", "never_observed", "missing",
///  "partly_missing", "gone", "not_in_plan"},
///  "objects": [{"id", "kind", "attributes", "status", "confirmations", "adjustments",
///               "moved_by"?: {"dx", "dy", "dtheta", "distance", "sigma_xy"},
///               "edges"?: [{"edge", "length", "backed", "seen_through", "observed", "beams_through", "beams_ended",
///                           "seen_through_stretches": [{"s0", "s1", "beams_through"}]}],
///               "verdicts"?: [{"verdict", "edge"?, "s0", "s1", "p0", "p1", "rule", "explanation"}]}],
///  "not_in_plan": [{"id", "p0", "p1", "length", "support", "source"}]}  (metres, radians; shares in [0, 1])
nlohmann::json as_built_json(const world::WorldState& state, const world::AsBuiltReport& report,
                             const world::PlanReport* evidence = nullptr);

/// One object's entry of as_built_json ("edges": the evidence of its edges, "verdicts": the rules' on it); `index`
/// is its place in the plan.
nlohmann::json object_as_built_json(const world::ObjectAsBuilt& entry, std::size_t index,
                                    const world::PlanReport* evidence);

/// One change: {"id", "key", "kind", "object"?, "edge"?, "element"?, "p0", "p1", "length", "confidence",
///  "stretch"?: [s0, s1], "evidence"?: {"backed", "seen_through", "observed", "length", "beams_through",
///  "beams_ended"}, "moved_by"?: {"dx", "dy", "dtheta", "distance", "sigma_xy"}, "support"?, "rule", "explanation"}.
nlohmann::json change_json(const world::Change& change);
/// {"version", "grid_revision", "changes": [change, ...]}.
nlohmann::json changes_json(const world::WorldState& state, const world::PlanReport& evidence,
                            const std::vector<world::Change>& changes);

}  // namespace wm::json_codec
