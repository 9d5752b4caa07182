// The world service's changes in the building: list, accept or reject, undo.
#include <algorithm>
#include <cmath>

#include "server/json/events_json.h"
#include "server/service/knowledge_facts.h"
#include "server/service/world_service.h"
#include "server/world/plan_edit.h"

namespace wm::service {

std::vector<world::Change> WorldService::changes(std::shared_ptr<const world::WorldState>& state,
                                                 std::shared_ptr<const world::PlanReport>& evidence) const {
  state = snapshot();
  evidence = plan_report();
  return plan_checks_.changes(*state, evidence.get());
}

ChangeOutcome WorldService::decide_change(const std::string& change_id, bool accept, std::string observer) {
  return run_command([this, &change_id, accept, &observer] {
    std::shared_ptr<const world::WorldState> state;
    std::shared_ptr<const world::PlanReport> evidence;
    const auto listed = changes(state, evidence);
    const auto change =
        std::find_if(listed.begin(), listed.end(), [&change_id](const world::Change& c) { return c.id == change_id; });
    if (change == listed.end())
      throw NotFound("no change '" + change_id + "' is listed now (GET /api/v1/changes lists them)");
    const auto before = world::current_plan(*state);
    ChangeOutcome outcome;
    outcome.change_id = change_id;
    std::optional<apriori::FloorPlan> plan;
    std::vector<std::int64_t> remove;
    std::string added;
    if (accept) {
      plan = world::plan_with_change(*state, *change, &added);
      if (change->kind == world::ChangeKind::new_wall)
        if (const auto number = world::WorldState::element_number(change->element_id)) remove.push_back(*number);
      if (!added.empty()) outcome.added_object = added;
    }
    const std::string subject = change->object_id.empty() ? change->element_id : change->object_id;
    std::string explanation = std::string(accept ? "accepted into the plan" : "rejected") + ": change " + change_id +
                              " (" + change->key + ", confidence " +
                              std::to_string(std::lround(change->confidence * 100)) + " %): " + change->explanation;
    if (!added.empty()) explanation += "; drawn as object " + added;
    auto p = MapWriter::own_observation(state, std::move(observer), "plan", "none");
    p.update = world::apply_plan_edit(*state, plan ? *plan : before, options_.map.world, remove, p.seq,
                                      accept ? rules::Action::accept : rules::Action::reject,
                                      accept ? "change_accepted" : "change_rejected", explanation,
                                      p.observation.observer, subject);
    const std::string payload =
        nlohmann::json{{"change", change_id}, {"verdict", accept ? "accepted" : "rejected"}}.dump();
    storage::Store::PlanChangeRecord record{change_id, accept ? "accepted" : "rejected",
                                            accept ? std::optional(before) : std::nullopt, 0};
    writer_.commit(p, [&] { store_.commit_plan_change({p.update, p.observation, payload}, plan, record); });
    outcome.decision = p.update.decisions.at(0);
    auto removed = world::removed_objects(*state, p.update.state);
    auto live = event_log_.begin();
    outcome.version = writer_.finish(std::move(p), live, std::move(removed)).version;
    if (accept) {
      sync_all_facts(engine_, *snapshot(), options_.map.world);
      plan_checks_.refresh(*snapshot(), std::nullopt);
    } else {
      plan_checks_.reject(change_id);
    }
    live.add(events::EventKind::change,
             [&] { return json_codec::change_event(change_id, accept ? "accepted" : "rejected", outcome.version); });
    return outcome;
  });
}

ChangeOutcome WorldService::undo_change(std::string observer) {
  return run_command([this, &observer] {
    const auto history = store_.plan_changes();
    if (history.empty()) throw Conflict("no change was accepted or rejected: there is nothing to undo");
    const auto& last = history.back();
    const auto state = snapshot();
    std::optional<apriori::FloorPlan> plan;
    if (last.verdict == "accepted" && last.plan_before) plan = last.plan_before;
    auto p = MapWriter::own_observation(state, std::move(observer), "plan", "none");
    const std::string explanation = "undo of decision " + std::to_string(last.decision_seq) + ": change " +
                                    last.change_id + " is no longer " + last.verdict +
                                    (plan ? "; the plan is back as it was before it" : "; it is listed again");
    p.update = world::apply_plan_edit(*state, plan ? *plan : world::current_plan(*state), options_.map.world, {}, p.seq,
                                      rules::Action::undo, "change_undone", explanation, p.observation.observer, "");
    const std::string payload = nlohmann::json{{"undo", last.decision_seq}, {"change", last.change_id}}.dump();
    writer_.commit(p, [&] { store_.commit_plan_change({p.update, p.observation, payload}, plan, std::nullopt); });
    ChangeOutcome outcome;
    outcome.change_id = last.change_id;
    outcome.decision = p.update.decisions.at(0);
    auto removed = world::removed_objects(*state, p.update.state);
    auto live = event_log_.begin();
    outcome.version = writer_.finish(std::move(p), live, std::move(removed)).version;
    if (plan) {
      sync_all_facts(engine_, *snapshot(), options_.map.world);
      plan_checks_.refresh(*snapshot(), std::nullopt);
    } else {
      plan_checks_.unreject(last.change_id);
    }
    live.add(events::EventKind::change,
             [&] { return json_codec::change_event(last.change_id, "undone", outcome.version); });
    return outcome;
  });
}

}  // namespace wm::service
