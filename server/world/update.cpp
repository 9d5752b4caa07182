#include "server/world/update.h"

#include <stdexcept>

namespace wm::world {
namespace {

// Where a matching candidate came from: an edge of a CAD object or an observed element.
struct CandidateRef {
  std::optional<std::size_t> object;  // index into state.objects
  std::size_t edge = 0;
  std::int64_t element = 0;  // element number when object is empty
};

struct Candidates {
  std::vector<fusion::LineSegment> segments;
  std::vector<CandidateRef> refs;
};

Candidates collect_candidates(const WorldState& state, const WorldOptions& options) {
  Candidates c;
  for (std::size_t i = 0; i < state.objects.size(); ++i) {
    const auto& object = state.objects[i];
    for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
      c.segments.push_back(apriori_edge(object, k, options));
      c.refs.push_back({i, k, 0});
    }
  }
  for (const auto& [number, element] : state.elements) {
    c.segments.push_back(element.segment);
    c.refs.push_back({std::nullopt, 0, number});
  }
  return c;
}

rules::DecisionQuery make_query(const WorldState& state, const Observation& observation, const fusion::LineSegment& seen,
                                const std::optional<fusion::MatchResult>& match, const Candidates& candidates) {
  rules::DecisionQuery q;
  q.source = observation.observer;
  q.rho_m = seen.line.rho_m;
  q.phi_rad = seen.line.phi_rad;
  q.length_m = seen.length_m();
  if (match) {
    const auto& ref = candidates.refs[match->index];
    if (ref.object) {
      const auto& id = state.objects[*ref.object].plan->id;
      q.element_id = edge_id(id, ref.edge);
      q.object_id = id;
    } else {
      q.element_id = "e" + std::to_string(ref.element);
    }
    q.mahalanobis_sq = match->mahalanobis_sq;
  }
  return q;
}

void make_fallback(DecisionRecord& record, const std::string& why) {
  record.explanation = "fallback (" + why + "); rules said " + record.action + " by " + record.rule;
  record.action = "add";
  record.rule = "fallback";
  record.fallback = true;
}

}  // namespace

UpdateResult apply_observation(const WorldState& current, const Observation& observation, std::int64_t observation_seq,
                               const WorldOptions& options, const Decide& decide) {
  UpdateResult result{current, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.last_observation_seq = observation_seq;

  for (std::size_t i = 0; i < observation.segments.size(); ++i) {
    const auto& seen = observation.segments[i].segment;
    // Matching runs against the map as changed by the earlier segments of the same request.
    const Candidates candidates = collect_candidates(state, options);
    const auto match = fusion::best_match(candidates.segments, seen, options.match);
    const auto query = make_query(state, observation, seen, match, candidates);
    const rules::Decision decision = decide(query);

    DecisionRecord record;
    record.seq = ++state.last_decision_seq;
    record.observation_seq = observation_seq;
    record.index = static_cast<std::int64_t>(i);
    record.action = decision.action;
    record.rule = decision.rule;
    record.explanation = decision.explanation;
    record.fallback = decision.fallback;
    record.element = query.element_id;
    record.object = query.object_id;
    if (match) record.mahalanobis_sq = match->mahalanobis_sq;
    record.observer = observation.observer;
    record.p0 = seen.p0();
    record.p1 = seen.p1();

    const CandidateRef* ref = match ? &candidates.refs[match->index] : nullptr;
    if (record.action == "merge" && !(ref && !ref->object)) {
      make_fallback(record, ref ? "merge needs an observed element, not a CAD edge" : "merge needs a match");
    } else if (record.action == "rigid_adjust" && !(ref && ref->object)) {
      make_fallback(record, "rigid_adjust needs a matched CAD object");
    } else if (record.action != "delete" && record.action != "merge" && record.action != "rigid_adjust" &&
               record.action != "add") {
      make_fallback(record, "action '" + record.action + "' is not known to the server");
    }

    if (record.action == "delete") {
      if (ref && ref->object) {
        auto& object = state.objects[*ref->object];
        ++object.confirmations;
        object.updated_version = state.version;
        result.changed_objects.insert(*ref->object);
      } else if (ref) {
        auto& element = state.elements.at(ref->element);
        ++element.support;
        element.updated_version = state.version;
        result.changed_elements.insert(ref->element);
      }
    } else if (record.action == "merge") {
      auto& element = state.elements.at(ref->element);
      element.segment = fusion::fuse(element.segment, seen);
      ++element.support;
      element.updated_version = state.version;
      result.changed_elements.insert(ref->element);
    } else if (record.action == "rigid_adjust") {
      auto& object = state.objects[*ref->object];
      try {
        object.body = object.body.updated(ref->edge, seen.line, apriori_edge_noise(object, ref->edge, options));
        ++object.adjustments;
        object.updated_version = state.version;
        result.changed_objects.insert(*ref->object);
      } catch (const std::invalid_argument& e) {
        make_fallback(record, std::string("rigid update failed: ") + e.what());
      }
    }
    if (record.action == "add") {
      Element element;
      element.number = state.next_element_number++;
      element.segment = seen;
      element.source = observation.source;
      element.observer = observation.observer;
      element.created_version = state.version;
      element.updated_version = state.version;
      record.element = element.id();
      record.object.reset();
      result.changed_elements.insert(element.number);
      state.elements.emplace(element.number, std::move(element));
    }
    result.decisions.push_back(std::move(record));
  }
  return result;
}

UpdateResult apply_floor_plan(const WorldState& current, const apriori::FloorPlan& plan, const WorldOptions& options) {
  UpdateResult result{current, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.plan_name = plan.name;
  state.objects = make_objects(plan, options, state.version);
  rebuild_object_index(state);
  for (std::size_t i = 0; i < state.objects.size(); ++i) result.changed_objects.insert(i);
  return result;
}

}  // namespace wm::world
