#include "server/service/knowledge_facts.h"

#include <string>

namespace wm::service {

rules::ElementFacts element_facts(const world::Element& e) {
  return {e.id(),    e.origin,           e.observer, e.segment.line.rho_m, e.segment.line.phi_rad, e.segment.length_m(),
          e.support, e.updated_at_unix_s};
}

rules::DecisionFacts decision_facts(const world::DecisionRecord& d, double at) {
  return {d.seq, std::string(rules::wire_name(d.action)), d.rule, d.element, d.object, d.observer, at};
}

std::vector<rules::ObjectFacts> object_facts(const world::WorldState& state, const world::WorldOptions& options) {
  std::vector<rules::ObjectFacts> result;
  result.reserve(state.objects.size());
  for (const auto& object : state.objects) {
    rules::ObjectFacts f;
    f.id = object.plan->id;
    f.kind = object.plan->kind;
    f.attributes = object.plan->attributes;
    for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
      const auto edge = world::apriori_edge(object, k, options);
      f.edges.push_back({world::edge_id(f.id, k), edge.line.rho_m, edge.line.phi_rad, edge.length_m()});
    }
    result.push_back(std::move(f));
  }
  return result;
}

void sync_all_facts(rules::Engine& engine, const world::WorldState& state, const world::WorldOptions& options) {
  engine.set_floor_plan(object_facts(state, options));
  std::vector<rules::ElementFacts> elements;
  elements.reserve(state.elements.size());
  for (const auto& [number, e] : state.elements) elements.push_back(element_facts(e));
  engine.set_elements(elements);
}

}  // namespace wm::service
