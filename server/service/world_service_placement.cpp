// The world service's floor-plan placement: place, undo, align to the grid, re-decide, georeference.
#include <atomic>
#include <cmath>
#include <cstdio>

#include "server/json/events_json.h"
#include "server/service/knowledge_facts.h"
#include "server/service/world_service.h"

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

PlacementOutcome WorldService::place_floor_plan(world::PlacementChange change, std::string payload_json) {
  return run_command([this, change = std::move(change), payload = std::move(payload_json)] {
    return place_on_writer(change, payload, false);
  });
}

PlacementOutcome WorldService::place_on_writer(const world::PlacementChange& change, const std::string& payload,
                                               bool undo) {
  const auto base = snapshot();
  if (base->objects.empty()) throw Conflict("no floor plan is loaded: there is nothing to place");
  auto p = MapWriter::own_observation(base, change.observer, "placement", "none");
  p.update = world::apply_placement(*base, change, p.seq);
  writer_.commit(p, [&] { store_.commit_placement({p.update, p.observation, payload}, undo); });
  const auto decision = p.update.decisions.at(0);
  const auto placement = p.update.state.placement;
  auto live = event_log_.begin();
  auto outcome = writer_.finish(std::move(p), live);
  // The rules see the edges where the plan now is, before the next request is decided.
  engine_.set_floor_plan(object_facts(*snapshot(), options_.map.world));
  plan_checks_.refresh(*snapshot(), std::nullopt);
  live.add(events::EventKind::placement, [&] {
    return json_codec::placement_event(outcome.version, placement, snapshot()->placement_cov, decision);
  });
  return {outcome.version, decision};
}

PlacementOutcome WorldService::undo_placement(std::string observer) {
  return run_command([this, observer = std::move(observer)] {
    const auto history = store_.placements();
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

AlignOutcome WorldService::align_floor_plan(AlignRequest request) {
  // The search runs on the calling thread, against a snapshot and a copy of the grid: the writer goes on meanwhile.
  // One at a time: a search takes a core for up to its time budget.
  if (aligning_.exchange(true)) throw Conflict("an alignment is running: try again when it has answered");
  struct Release {
    std::atomic<bool>& flag;
    ~Release() { flag = false; }
  } release{aligning_};
  const auto state = snapshot();
  if (state->objects.empty()) throw Conflict("no floor plan is loaded: there is nothing to align");
  auto raster = grid_.probability_raster();
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
  outcome.placement = run_command([&] {
    const auto now = snapshot();
    if (!(now->placement == outcome.before) || now->plan_name != state->plan_name ||
        now->objects.size() != state->objects.size())
      throw Conflict("the plan or its placement changed during the search: nothing applied; align again");
    return place_on_writer(change, payload.dump(), false);
  });
  outcome.applied = true;
  if (request.redecide) outcome.redecided = redecide_elements(request.observer);
  return outcome;
}

RedecideOutcome WorldService::redecide_elements(std::string observer) {
  return run_command([this, observer = std::move(observer)] { return redecide_on_writer(observer); });
}

RedecideOutcome WorldService::redecide_on_writer(const std::string& observer) {
  const auto base = snapshot();
  RedecideOutcome outcome;
  const std::int64_t seq = base->last_observation_seq + 1;
  world::UpdateResult total{*base, {}, {}, {}, {}};
  const auto decide = [this](const rules::DecisionQuery& q) { return engine_.decide(q); };
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
    auto result = world::apply_observation(without, observation, seq, options_.map.world, decide);
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
  writer_.commit(p, [&] { store_.commit_observation(p.update, p.observation, payload); });
  auto live = event_log_.begin();
  auto done = writer_.finish(std::move(p), live);
  sync_all_facts(engine_, *snapshot(), options_.map.world);
  outcome.version = done.version;
  outcome.decisions = std::move(done.decisions);
  return outcome;
}

std::int64_t WorldService::set_georeference(std::optional<apriori::Georeference> georeference) {
  if (georeference) apriori::validate(*georeference);
  return run_command([this, georeference] {
    world::WorldState state = *snapshot();
    state.georeference = georeference;
    ++state.version;
    store_.commit_georeference(state);
    const auto version = state.version;
    writer_.published().publish(std::move(state));
    emit(events::EventKind::georeference, [&] { return json_codec::georeference_event(version); });
    return version;
  });
}

}  // namespace wm::service
