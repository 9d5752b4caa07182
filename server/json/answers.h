#pragma once

// JSON of what the service answers beyond single world values (see codec.h for those): decision lists and the
// as-built report.
#include <nlohmann/json.hpp>
#include <vector>

#include "server/world/as_built.h"
#include "server/world/update.h"

namespace wm::json_codec {

/// [decision, ...] in order, each as decision_json.
nlohmann::json decisions_json(const std::vector<world::DecisionRecord>& decisions);

/// {"plan", "version", "summary": {"objects", "confirmed", "moved", "never_observed", "not_in_plan"},
///  "objects": [{"id", "kind", "attributes", "status", "confirmations", "adjustments",
///               "moved_by"?: {"dx", "dy", "dtheta", "distance", "sigma_xy"}}],
///  "not_in_plan": [{"id", "p0", "p1", "length", "support", "source"}]}  (metres, radians)
nlohmann::json as_built_json(const world::WorldState& state, const world::AsBuiltReport& report);

}  // namespace wm::json_codec
