#include "server/service/world_service.h"

#include <algorithm>
#include <chrono>
#include <iostream>

namespace wm::service {
namespace {

double now_unix_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

rules::ElementFacts element_facts(const world::Element& e) {
  return {e.id(),
          e.source,
          e.observer,
          e.segment.line.rho_m,
          e.segment.line.phi_rad,
          e.segment.length_m(),
          e.support,
          e.updated_at_unix_s};
}

rules::DecisionFacts decision_facts(const world::DecisionRecord& d, double at) {
  return {d.seq, d.action, d.rule, d.element, d.object, d.observer, at};
}

}  // namespace

WorldService::WorldService(const ServiceOptions& options, storage::Store& store, rules::Engine& engine)
    : options_(options), store_(store), engine_(engine) {
  snapshot_ = std::make_shared<const world::WorldState>(store_.load(options_.world));
  writer_ = std::make_unique<PrologWorker>(engine_, options_.max_queued_requests, "world model's write");
  reader_ = std::make_unique<PrologWorker>(engine_, 64, "knowledge-base query");
  // The knowledge base mirrors the committed map; fill it before the first request is taken.
  writer_->run([this] {
    sync_all_facts(*snapshot());
    std::vector<rules::DecisionFacts> recent;
    for (const auto& d : store_.latest_decisions(options_.decision_facts_kept)) recent.push_back(decision_facts(d, 0));
    engine_.add_decisions(recent, options_.decision_facts_kept);
    return 0;
  });
  if (options_.watch_rules_dir) {
    watcher_ = std::make_unique<RulesWatcher>(*options_.watch_rules_dir, [this] { on_rules_changed(); });
  }
}

WorldService::~WorldService() {
  watcher_.reset();
  reader_.reset();
  writer_.reset();
}

std::shared_ptr<const world::WorldState> WorldService::snapshot() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_;
}

void WorldService::publish(world::WorldState state) {
  auto next = std::make_shared<const world::WorldState>(std::move(state));
  std::lock_guard lock(snapshot_mutex_);
  snapshot_ = std::move(next);
}

std::vector<rules::ObjectFacts> WorldService::object_facts(const world::WorldState& state) const {
  std::vector<rules::ObjectFacts> result;
  result.reserve(state.objects.size());
  for (const auto& object : state.objects) {
    rules::ObjectFacts f;
    f.id = object.plan->id;
    f.kind = object.plan->kind;
    f.attributes = object.plan->attributes;
    for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
      const auto edge = world::apriori_edge(object, k, options_.world);
      f.edges.push_back({world::edge_id(f.id, k), edge.line.rho_m, edge.line.phi_rad, edge.length_m()});
    }
    result.push_back(std::move(f));
  }
  return result;
}

void WorldService::sync_all_facts(const world::WorldState& state) {
  engine_.set_floor_plan(object_facts(state));
  std::vector<rules::ElementFacts> elements;
  elements.reserve(state.elements.size());
  for (const auto& [number, e] : state.elements) elements.push_back(element_facts(e));
  engine_.set_elements(elements);
}

WorldService::PrimitivesOutcome WorldService::post_primitives(world::Observation observation, std::string payload_json) {
  return writer_->run([this, observation = std::move(observation), payload = std::move(payload_json)]() mutable {
    const auto current = snapshot();
    const std::int64_t seq = current->last_observation_seq + 1;
    observation.received_at_unix_s = now_unix_s();
    auto update = world::apply_observation(*current, observation, seq, options_.world,
                                           [this](const rules::DecisionQuery& q) { return engine_.decide(q); });
    try {
      // The rules' prune/3 sees the map as this update leaves it.
      std::vector<rules::ElementFacts> upserts;
      for (auto number : update.changed_elements) upserts.push_back(element_facts(update.state.elements.at(number)));
      engine_.update_elements(upserts, {});
      const auto orders = engine_.prune_orders(options_.max_prune_per_update);
      if (!orders.empty()) {
        world::apply_prune(update, orders, seq, observation.observer);
        std::vector<std::string> removed;
        for (auto number : update.removed_elements) removed.push_back("e" + std::to_string(number));
        engine_.update_elements({}, removed);
      }
      store_.commit_observation(update, observation, payload);
    } catch (...) {
      sync_all_facts(*current);  // nothing was applied: the facts go back to the committed map
      throw;
    }
    const bool moved = std::any_of(update.decisions.begin(), update.decisions.end(),
                                   [](const auto& d) { return d.action == "rigid_adjust"; });
    std::vector<rules::DecisionFacts> logged;
    for (const auto& d : update.decisions) {
      logged.push_back(decision_facts(d, observation.received_at_unix_s));
      if (d.fallback) std::cerr << "wmd: decision " << d.seq << " fell back to add: " << d.explanation << "\n";
    }
    PrimitivesOutcome outcome{seq, update.state.version, update.decisions};
    publish(std::move(update.state));
    engine_.add_decisions(logged, options_.decision_facts_kept);
    // Edge facts are in the world frame: a moved object must be seen where it is now by the next rule call.
    if (moved) engine_.set_floor_plan(object_facts(*snapshot()));
    return outcome;
  });
}

std::int64_t WorldService::load_floor_plan(apriori::FloorPlan plan) {
  return writer_->run([this, plan = std::move(plan)] {
    const auto current = snapshot();
    auto update = world::apply_floor_plan(*current, plan, options_.world);
    auto new_facts = object_facts(update.state);
    store_.commit_floor_plan(update, plan);
    const auto version = update.state.version;
    publish(std::move(update.state));
    engine_.set_floor_plan(new_facts);
    return version;
  });
}

rules::RulesStatus WorldService::rules_status() { return engine_.status(); }

rules::RulesStatus WorldService::reload_rules() {
  return writer_->run([this] { return engine_.reload(); });
}

void WorldService::on_rules_changed() {
  try {
    const auto status = reload_rules();
    std::cerr << "wmd: rules reloaded (generation " << status.generation << ", " << status.files.size() << " files)\n";
  } catch (const rules::RuleError& e) {
    std::cerr << "wmd: rules edit rejected, the previous rules stay active:\n" << e.what() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "wmd: rules reload failed: " << e.what() << "\n";
  }
}

rules::QueryResult WorldService::query(const std::string& goal, std::size_t max_solutions) {
  return reader_->run([this, goal, max_solutions] { return engine_.query(goal, max_solutions); });
}

DryRunOutcome WorldService::dry_run(const rules::RuleText& candidate, std::size_t count) {
  return reader_->run([this, candidate, count] {
    const auto recorded = store_.latest_decisions(count);
    std::vector<rules::DecisionQuery> queries;
    queries.reserve(recorded.size());
    for (const auto& d : recorded) queries.push_back(d.query());
    const auto answers = engine_.dry_run(candidate, queries);
    DryRunOutcome outcome;
    outcome.redecided = recorded.size();
    for (std::size_t i = 0; i < recorded.size(); ++i) {
      const auto& before = recorded[i];
      const auto& after = answers[i];
      if (before.rule != after.rule || before.action != after.action)
        outcome.changes.push_back({before, after});
    }
    return outcome;
  });
}

}  // namespace wm::service
