#include "server/service/map_writer.h"

#include <algorithm>
#include <chrono>

#include "server/json/events_json.h"
#include "server/service/knowledge_facts.h"

namespace wm::service {

double now_unix_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

MapWriter::MapWriter(const MapWriterOptions& options, world::WorldState initial, rules::Engine& engine,
                     common::Diagnostics& diagnostics)
    : options_(options), engine_(engine), diagnostics_(diagnostics), published_(std::move(initial)) {}

PreparedUpdate MapWriter::own_observation(std::shared_ptr<const world::WorldState> base, std::string observer,
                                          std::string origin, std::string sensor) {
  PreparedUpdate p;
  p.seq = base->last_observation_seq + 1;
  p.base = std::move(base);
  p.observation.observer = std::move(observer);
  p.observation.origin = std::move(origin);
  p.observation.sensor = std::move(sensor);
  p.observation.received_at_unix_s = now_unix_s();
  return p;
}

PreparedUpdate MapWriter::prepare(std::shared_ptr<const world::WorldState> base, world::Observation observation) {
  PreparedUpdate p;
  p.base = std::move(base);
  p.seq = p.base->last_observation_seq + 1;
  observation.received_at_unix_s = now_unix_s();
  p.update = world::apply_observation(*p.base, observation, p.seq, options_.world,
                                      [this](const rules::DecisionQuery& q) { return engine_.decide(q); });
  try {
    // The rules' prune/3 sees the map as this update leaves it (without the elements a join removed).
    follow_elements(p.update, true);
    prune(p, observation.observer);
    // Edge facts are in the world frame: a moved object must be seen where it is now by the next rule call.
    if (std::any_of(p.update.decisions.begin(), p.update.decisions.end(),
                    [](const auto& d) { return d.action == rules::Action::rigid_adjust; }))
      engine_.set_floor_plan(object_facts(p.update.state, options_.world));
  } catch (...) {
    sync_all_facts(engine_, *p.base, options_.world);  // nothing was applied: the facts go back to the map before
    throw;
  }
  p.observation = std::move(observation);
  return p;
}

void MapWriter::follow_elements(const world::UpdateResult& update, bool removals) {
  std::vector<rules::ElementFacts> upserts;
  for (auto number : update.changed_elements) upserts.push_back(element_facts(update.state.elements.at(number)));
  std::vector<std::string> removed;
  if (removals)
    for (auto number : update.removed_elements) removed.push_back(world::element_id(number));
  engine_.update_elements(upserts, removed);
}

void MapWriter::prune(PreparedUpdate& p, const std::string& observer) {
  const auto orders = engine_.prune_orders(options_.max_prune_per_update);
  if (orders.empty()) return;
  if (p.update.decisions.empty()) {  // nothing else changed: the pruning is the new version
    p.update.state.version = p.base->version + 1;
    p.update.state.last_observation_seq = p.seq;
  }
  world::apply_prune(p.update, orders, p.seq, observer);
  std::vector<std::string> removed;
  for (auto number : p.update.removed_elements) removed.push_back(world::element_id(number));
  engine_.update_elements({}, removed);
}

void MapWriter::commit(const PreparedUpdate& prepared, const std::function<void()>& store_write) {
  try {
    store_write();
  } catch (...) {
    sync_all_facts(engine_, *prepared.base, options_.world);  // nothing was applied: back to the committed map
    throw;
  }
}

PrimitivesOutcome MapWriter::finish(PreparedUpdate prepared, EventLog::Commit& live,
                                    std::set<std::string> removed_objects) {
  auto& update = prepared.update;
  const auto& observation = prepared.observation;
  const auto seq = prepared.seq;
  std::vector<rules::DecisionFacts> logged;
  for (const auto& d : update.decisions) {
    logged.push_back(decision_facts(d, observation.received_at_unix_s));
    if (d.fallback)
      diagnostics_.report(common::Severity::warning, "decisions",
                          "decision " + std::to_string(d.seq) + " fell back to add: " + d.explanation);
  }
  PrimitivesOutcome outcome{seq, update.state.version, update.decisions, false};
  live.add(events::EventKind::update,
           [&] { return json_codec::update_event(seq, observation.origin, update, removed_objects, options_.world); });
  std::set<std::string> removed;
  for (auto number : update.removed_elements) removed.insert(world::element_id(number));
  published_.publish(std::move(update.state), MapRemovals{std::move(removed), std::move(removed_objects)});
  // Committed and published: the request is answered as applied whatever happens here.
  try {
    engine_.add_decisions(logged, options_.decision_facts_kept);
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::warning, "rules",
                        "decision facts of observation " + std::to_string(seq) + " not kept: " + e.what());
  }
  return outcome;
}

void MapWriter::restore_facts(const world::WorldState& state, const std::string& after) {
  try {
    sync_all_facts(engine_, state, options_.world);
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::error, "rules", "rule facts not restored after " + after + ": " + e.what());
  }
}

}  // namespace wm::service
