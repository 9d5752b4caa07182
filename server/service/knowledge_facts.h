#pragma once

#include <vector>

#include "rules/engine.h"
#include "server/world/update.h"
#include "server/world/world_state.h"

namespace wm::service {

/// The knowledge base's view of the map: the facts the rules read, made from the world model's values.

/// Every plan object with its attributes and its edges where they are drawn now (placement and pose applied).
std::vector<rules::ObjectFacts> object_facts(const world::WorldState& state, const world::WorldOptions& options);
rules::ElementFacts element_facts(const world::Element& element);
/// A logged decision, made at `at_unix_s`.
rules::DecisionFacts decision_facts(const world::DecisionRecord& decision, double at_unix_s);
/// Replaces the plan's and the elements' facts with those of `state` (the decisions stay).
void sync_all_facts(rules::Engine& engine, const world::WorldState& state, const world::WorldOptions& options);

}  // namespace wm::service
