// A map's plan commands: load, place, undo, align to the grid, re-decide, georeference, and the changes in the
// building (list, accept or reject, undo).
#include "server/service/plan_commands.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "server/json/events_json.h"
#include "server/service/knowledge_facts.h"
#include "server/world/plan_edit.h"

namespace wm::service {

namespace {

// Every drawn edge of the plan in the drawing's frame (objects at their drawn poses, so a table the robots moved
// does not pull the search); only the solid objects' when the plan marks any as solid, since furniture moves.
std::vector<fusion::DrawnEdge> drawn_edges(const world::WorldState& state) {
  bool any_solid = false;
  for (const auto& object : state.objects) any_solid = any_solid || object.plan->has_attribute("solid");
  std::vector<fusion::DrawnEdge> edges;
  for (const auto& object : state.objects) {
    if (any_solid && !object.plan->has_attribute("solid")) continue;
    for (const auto& e : object.plan->edges())
      edges.push_back({object.plan->pose.transform_point(e.p0), object.plan->pose.transform_point(e.p1)});
  }
  return edges;
}

std::string placement_text(const fusion::Similarity2D& p) {
  char text[160];
  std::snprintf(text, sizeof text, "x %.3f m, y %.3f m, theta %.3f deg, scale %.6g", p.x_m, p.y_m,
                p.theta_rad * 180.0 / 3.14159265358979323846, p.scale);
  return text;
}

}  // namespace

std::int64_t PlanCommands::load_floor_plan(apriori::FloorPlan plan) {
  return on_writer([this, plan = std::move(plan)] {
    const auto current = snapshot();
    auto update = world::apply_floor_plan(*current, plan, world_options());
    auto new_facts = object_facts(update.state, world_options());
    parts_.store.commit_floor_plan(update, plan);
    const auto version = update.state.version;
    MapRemovals removed;  // the objects of the old plan that the new one does not have
    removed.objects = world::removed_objects(*current, update.state);
    parts_.writer.published().publish(std::move(update.state), std::move(removed));
    parts_.engine.set_floor_plan(new_facts);
    parts_.plan_checks.refresh(*snapshot(), std::nullopt);
    parts_.events.publish(events::EventKind::floorplan,
                          [&] { return json_codec::floorplan_event(version, plan.name, plan.objects.size()); });
    return version;
  });
}

void PlanCommands::follow_plan(Facts facts) {
  const auto map = snapshot();
  if (facts == Facts::objects)
    parts_.engine.set_floor_plan(object_facts(*map, world_options()));
  else
    sync_all_facts(parts_.engine, *map, world_options());
  parts_.plan_checks.refresh(*map, std::nullopt);
}

PlacementOutcome PlanCommands::place(world::PlacementChange change, std::string payload_json) {
  return on_writer([this, change = std::move(change), payload = std::move(payload_json)] {
    return place_on_writer(change, payload, false);
  });
}

PlacementOutcome PlanCommands::place_on_writer(const world::PlacementChange& change, const std::string& payload,
                                               bool undo) {
  const auto base = snapshot();
  if (base->objects.empty()) throw Conflict("no floor plan is loaded: there is nothing to place");
  auto p = MapWriter::own_observation(base, change.observer, "placement", "none");
  p.update = world::apply_placement(*base, change, p.seq);
  parts_.writer.commit(p, [&] { parts_.store.commit_placement({p.update, p.observation, payload}, undo); });
  const auto decision = p.update.decisions.at(0);
  const auto placement = p.update.state.placement;
  auto live = parts_.events.begin();
  auto outcome = parts_.writer.finish(std::move(p), live);
  // The rules see the edges where the plan now is, before the next request is decided.
  follow_plan(Facts::objects);
  live.add(events::EventKind::placement, [&] {
    return json_codec::placement_event(outcome.version, placement, snapshot()->placement_cov, decision);
  });
  return {outcome.version, decision};
}

PlacementOutcome PlanCommands::undo_placement(std::string observer) {
  return on_writer([this, observer = std::move(observer)] {
    const auto history = parts_.store.placements();
    if (history.empty()) throw Conflict("the plan is placed as drawn: there is no placement to undo");
    world::PlacementChange change;
    if (history.size() >= 2) {
      change.placement = history[history.size() - 2].placement;
      change.cov = history[history.size() - 2].cov;
    }
    change.rule = "placement_undone";
    change.explanation = "undo of decision " + std::to_string(history.back().decision_seq) + ": back to " +
                         placement_text(change.placement);
    change.observer = observer;
    return place_on_writer(change, "{\"undo\": " + std::to_string(history.back().decision_seq) + "}", true);
  });
}

AlignOutcome PlanCommands::align(AlignRequest request) {
  // The search runs on the calling thread, against a snapshot and a copy of the grid: the writer goes on meanwhile.
  // One at a time: a search takes a core for up to its time budget.
  if (aligning_.exchange(true)) throw Conflict("an alignment is running: try again when it has answered");
  struct Release {
    std::atomic<bool>& flag;
    ~Release() { flag = false; }
  } release{aligning_};
  const auto state = snapshot();
  if (state->objects.empty()) throw Conflict("no floor plan is loaded: there is nothing to align");
  auto raster = parts_.grid.probability_raster();
  if (!raster) throw Conflict("the grid is empty: post scans before aligning the plan");
  fusion::ObservedMap observed{raster->geometry, std::move(raster->p), {}};
  // Points along the elements at the grid's cell, within the grid's bounds (a client's element may be km long).
  const auto& g = observed.geometry;
  const double step = g.resolution_m();
  const Eigen::Vector2d lo = g.origin_m();
  const Eigen::Vector2d hi =
      lo + step * Eigen::Vector2d(static_cast<double>(g.width()), static_cast<double>(g.height()));
  for (const auto& [number, e] : state->elements) {
    const Eigen::Vector2d a = e.segment.p0(), b = e.segment.p1();
    const double n = std::min(std::ceil((b - a).norm() / step), 1e5);
    for (double i = 0; i <= n; ++i) {
      const Eigen::Vector2d p = a + (b - a) * (i / std::max(n, 1.0));
      if ((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all()) observed.element_points.push_back(p);
    }
  }
  AlignOutcome outcome;
  outcome.before = state->placement;
  const auto edges = drawn_edges(*state);
  outcome.edges = edges.size();
  request.search.initial = state->placement;
  if (!request.scale_given) request.search.scale_min = request.search.scale_max = state->placement.scale;
  try {
    outcome.result = fusion::register_plan(edges, observed, request.search);
  } catch (const fusion::RegistrationError& e) {
    // No occupied cell is the map's state, not a bad request.
    if (std::string(e.what()).find("no occupied cell") != std::string::npos) throw Conflict(e.what());
    throw;
  }
  const auto& r = outcome.result;
  if (r.cancelled)
    outcome.verdict = "cancelled";
  else if (r.timed_out)
    outcome.verdict = "timed_out";
  else if (r.best.score < request.min_score)
    outcome.verdict = "low_score";
  else if (r.best.coverage < request.min_coverage)
    outcome.verdict = "low_coverage";
  else if (r.ambiguous && !request.apply_ambiguous)
    outcome.verdict = "ambiguous";
  else if (!request.apply)
    outcome.verdict = "preview";
  else
    outcome.verdict = "applied";
  if (outcome.verdict != "applied") return outcome;
  world::PlacementChange change;
  change.placement = r.best.placement;
  change.cov = r.covariance;
  change.rule = "plan_aligned";
  char text[256];
  std::snprintf(text, sizeof text, "aligned to the grid: %s; score %.3f over %.0f %% of the plan%s",
                placement_text(r.best.placement).c_str(), r.best.score, 100 * r.best.coverage,
                r.ambiguous ? " (ambiguous, applied as asked)" : "");
  change.explanation = text;
  change.observer = request.observer;
  nlohmann::json payload = {{"align", {{"score", r.best.score}, {"coverage", r.best.coverage}}}};
  // Applied only to the plan and placement it was searched for: a plan loaded or placed meanwhile wins.
  outcome.placement = on_writer([&] {
    const auto now = snapshot();
    if (!(now->placement == outcome.before) || now->plan_name != state->plan_name ||
        now->objects.size() != state->objects.size())
      throw Conflict("the plan or its placement changed during the search: nothing applied; align again");
    return place_on_writer(change, payload.dump(), false);
  });
  outcome.applied = true;
  if (request.redecide) outcome.redecided = redecide(request.observer);
  return outcome;
}

RedecideOutcome PlanCommands::redecide(std::string observer) {
  return on_writer([this, observer = std::move(observer)] { return redecide_on_writer(observer); });
}

RedecideOutcome PlanCommands::redecide_on_writer(const std::string& observer) {
  const auto base = snapshot();
  RedecideOutcome outcome;
  const std::int64_t seq = base->last_observation_seq + 1;
  world::UpdateResult total{*base, {}, {}, {}, {}};
  const auto decide = [this](const rules::DecisionQuery& q) { return parts_.engine.decide(q); };
  std::int64_t index = 0;
  for (const auto& [number, element] : base->elements) {
    ++outcome.elements;
    const auto* current = total.state.elements.find(number);
    if (!current) continue;  // merged into another element already
    world::WorldState without = total.state;
    without.elements.erase(number);
    world::Observation observation;
    observation.observer = observer;
    observation.origin = current->origin;
    observation.sensor = "redecide";
    observation.received_at_unix_s = now_unix_s();
    observation.segments.push_back({current->segment});
    auto result = world::apply_observation(without, observation, seq, world_options(), decide);
    const auto action = result.decisions.at(0).action;
    if (action != rules::Action::confirm && action != rules::Action::merge && action != rules::Action::rigid_adjust)
      continue;  // the rules would keep it: it stays as it is, with its history
    for (auto& d : result.decisions) {
      d.index = index;
      d.explanation = "redecided " + element.id() + ": " + d.explanation;
      d.matched_element = d.matched_element ? d.matched_element : std::optional<std::string>(element.id());
      total.decisions.push_back(d);
    }
    ++index;
    total.removed_elements.insert(number);
    total.changed_elements.erase(number);
    for (const auto n : result.changed_elements) total.changed_elements.insert(n);
    // Elements a join removed, also those this redecide created (their rows must not be written).
    for (const auto n : result.removed_elements) total.removed_elements.insert(n);
    for (const auto i : result.changed_objects) total.changed_objects.insert(i);
    total.state = std::move(result.state);
  }
  if (total.decisions.empty()) return {outcome.elements, base->version, {}};
  for (const auto n : total.removed_elements) total.changed_elements.erase(n);
  total.state.version = base->version + 1;
  total.state.last_observation_seq = seq;
  auto p = MapWriter::own_observation(base, observer, "redecide", "none");
  p.update = std::move(total);
  const std::string payload = "{\"redecide\": " + std::to_string(outcome.elements) + "}";
  parts_.writer.commit(p, [&] { parts_.store.commit_observation(p.update, p.observation, payload); });
  auto live = parts_.events.begin();
  auto done = parts_.writer.finish(std::move(p), live);
  sync_all_facts(parts_.engine, *snapshot(), world_options());
  outcome.version = done.version;
  outcome.decisions = std::move(done.decisions);
  return outcome;
}

std::int64_t PlanCommands::set_georeference(std::optional<apriori::Georeference> georeference) {
  if (georeference) apriori::validate(*georeference);
  return on_writer([this, georeference] {
    world::WorldState state = *snapshot();
    state.georeference = georeference;
    ++state.version;
    parts_.store.commit_georeference(state);
    const auto version = state.version;
    parts_.writer.published().publish(std::move(state));
    parts_.events.publish(events::EventKind::georeference, [&] { return json_codec::georeference_event(version); });
    return version;
  });
}

std::vector<world::Change> PlanCommands::changes(std::shared_ptr<const world::WorldState>& state,
                                                 std::shared_ptr<const world::PlanReport>& evidence) const {
  state = snapshot();
  evidence = parts_.plan_checks.report();
  return parts_.plan_checks.changes(*state, evidence.get());
}

ChangeOutcome PlanCommands::decide_change(const std::string& change_id, bool accept, std::string observer) {
  return on_writer([this, &change_id, accept, &observer] {
    std::shared_ptr<const world::WorldState> state;
    std::shared_ptr<const world::PlanReport> evidence;
    const auto listed = changes(state, evidence);
    const auto change =
        std::find_if(listed.begin(), listed.end(), [&change_id](const world::Change& c) { return c.id == change_id; });
    if (change == listed.end())
      throw NotFound("no change '" + change_id + "' is listed now (GET /api/v1/changes lists them)");
    const auto before = world::current_plan(*state);
    std::optional<apriori::FloorPlan> plan;
    std::vector<std::int64_t> remove;
    std::string added;
    if (accept) {
      plan = world::plan_with_change(*state, *change, &added);
      if (change->kind == world::ChangeKind::new_wall)
        if (const auto number = world::WorldState::element_number(change->element_id)) remove.push_back(*number);
    }
    const std::string subject = change->object_id.empty() ? change->element_id : change->object_id;
    std::string explanation = std::string(accept ? "accepted into the plan" : "rejected") + ": change " + change_id +
                              " (" + change->key + ", confidence " +
                              std::to_string(std::lround(change->confidence * 100)) + " %): " + change->explanation;
    if (!added.empty()) explanation += "; drawn as object " + added;
    auto p = MapWriter::own_observation(state, std::move(observer), "plan", "none");
    p.update = world::apply_plan_edit(*state, plan ? *plan : before, world_options(), remove, p.seq,
                                      accept ? rules::Action::accept : rules::Action::reject,
                                      accept ? "change_accepted" : "change_rejected", explanation,
                                      p.observation.observer, subject);
    const std::string payload =
        nlohmann::json{{"change", change_id}, {"verdict", accept ? "accepted" : "rejected"}}.dump();
    storage::Store::PlanChangeRecord record{change_id, accept ? "accepted" : "rejected",
                                            accept ? std::optional(before) : std::nullopt, 0};
    auto outcome = commit_change_edit(std::move(p), *state, change_id, payload, plan, record);
    if (!added.empty()) outcome.added_object = added;
    return outcome;
  });
}

ChangeOutcome PlanCommands::commit_change_edit(PreparedUpdate p, const world::WorldState& state,
                                               const std::string& change_id, const std::string& payload,
                                               const std::optional<apriori::FloorPlan>& plan,
                                               const std::optional<storage::Store::PlanChangeRecord>& push) {
  parts_.writer.commit(p, [&] { parts_.store.commit_plan_change({p.update, p.observation, payload}, plan, push); });
  ChangeOutcome outcome;
  outcome.change_id = change_id;
  outcome.decision = p.update.decisions.at(0);
  auto removed = world::removed_objects(state, p.update.state);
  auto live = parts_.events.begin();
  outcome.version = parts_.writer.finish(std::move(p), live, std::move(removed)).version;
  if (plan)
    follow_plan(Facts::all);
  else if (push)
    parts_.plan_checks.reject(change_id);
  else
    parts_.plan_checks.unreject(change_id);
  const std::string status = push ? push->verdict : "undone";
  live.add(events::EventKind::change, [&] { return json_codec::change_event(change_id, status, outcome.version); });
  return outcome;
}

ChangeOutcome PlanCommands::undo_change(std::string observer) {
  return on_writer([this, &observer] {
    const auto history = parts_.store.plan_changes();
    if (history.empty()) throw Conflict("no change was accepted or rejected: there is nothing to undo");
    const auto& last = history.back();
    const auto state = snapshot();
    std::optional<apriori::FloorPlan> plan;
    if (last.verdict == "accepted" && last.plan_before) plan = last.plan_before;
    auto p = MapWriter::own_observation(state, std::move(observer), "plan", "none");
    const std::string explanation = "undo of decision " + std::to_string(last.decision_seq) + ": change " +
                                    last.change_id + " is no longer " + last.verdict +
                                    (plan ? "; the plan is back as it was before it" : "; it is listed again");
    p.update = world::apply_plan_edit(*state, plan ? *plan : world::current_plan(*state), world_options(), {}, p.seq,
                                      rules::Action::undo, "change_undone", explanation, p.observation.observer, "");
    const std::string payload = nlohmann::json{{"undo", last.decision_seq}, {"change", last.change_id}}.dump();
    return commit_change_edit(std::move(p), *state, last.change_id, payload, plan, std::nullopt);
  });
}

}  // namespace wm::service
