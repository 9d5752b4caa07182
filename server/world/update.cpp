#include "server/world/update.h"

#include <stdexcept>
#include <string>
#include <string_view>

namespace wm::world {
namespace {

// Candidates farther than this (box to box, plus the gap allowance) cannot pass the segment gate of any sane
// tolerance; it only saves work.
constexpr double kCandidateMarginM = 1.0;

// Where a matching candidate came from: an edge of a CAD object or an observed element.
struct CandidateRef {
  std::optional<std::size_t> object;  // index into state.objects
  std::size_t edge = 0;
  std::int64_t element = 0;  // element number when object is empty
};

// How far (box to box) a candidate may be and still be worth the gate.
double candidate_margin(const fusion::MatchOptions& match) { return kCandidateMarginM + match.max_gap_m; }

struct Candidates {
  std::vector<fusion::LineSegment> segments;
  std::vector<CandidateRef> refs;
};

// What can match `seen`: the CAD edges and elements whose boxes come near it (the gate tolerances stay well
// inside the margin).
Candidates collect_candidates(const WorldState& state, const fusion::LineSegment& seen, const WorldOptions& options) {
  const Box near = Box::of(seen, candidate_margin(options.match));
  Candidates c;
  for (const auto& [i, k] : state.objects.edges_near(near)) {
    auto edge = apriori_edge(state.objects[i], k, options);
    if (!Box::of(edge).overlaps(near)) continue;
    c.segments.push_back(std::move(edge));
    c.refs.push_back({i, k, 0});
  }
  const auto seen_moments = fusion::SegmentMoments::of(seen);
  for (const auto number : state.elements.near(near)) {
    const Element& element = state.elements.at(number);
    if (!Box::of(element.segment).overlaps(near)) continue;
    // Taking `seen` in would bend the element: not the same straight wall, whatever the gate says.
    if ((element.moments + seen_moments).rms_offset_m() > options.max_straightness_rms_m) continue;
    c.segments.push_back(element.segment);
    c.refs.push_back({std::nullopt, 0, number});
  }
  return c;
}

rules::DecisionQuery make_query(const WorldState& state, const Observation& observation,
                                const fusion::LineSegment& seen, const std::optional<fusion::MatchResult>& match,
                                const Candidates& candidates) {
  rules::DecisionQuery q;
  q.observer = observation.observer;
  q.origin = observation.origin;
  q.sensor = observation.sensor;
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
      q.element_id = element_id(ref.element);
    }
    q.mahalanobis_sq = match->mahalanobis_sq;
  }
  return q;
}

std::vector<double> line_numbers(const fusion::LineFeature& line) {
  return {line.rho_m, line.phi_rad, line.cov(0, 0), line.cov(0, 1), line.cov(1, 0), line.cov(1, 1)};
}

std::vector<double> pose_numbers(const fusion::RigidObject& body) {
  std::vector<double> v{body.pose().x_m, body.pose().y_m, body.pose().theta_rad};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) v.push_back(body.pose_cov()(r, c));
  return v;
}

// The segment a decision is about, as the log keeps it.
void record_observed(DecisionRecord& record, const fusion::LineSegment& segment) {
  record.p0 = segment.p0();
  record.p1 = segment.p1();
  record.rho_m = segment.line.rho_m;
  record.phi_rad = segment.line.phi_rad;
  record.observed_cov = segment.line.cov;
}

// The element's line after it took in more views: the Kalman update gives the covariance (floored, see
// WorldOptions::fusion) and the extent; the line itself is the best fit of everything the element was built from.
// The views' own scatter across the line (the pose error they do not share) floors the offset uncertainty at the
// midpoint, so a view as far off as the ones already taken in still matches.
fusion::LineSegment fused_and_refit(const fusion::LineSegment& fused, const fusion::SegmentMoments& moments) {
  return fusion::with_covariance_floor(moments.refit(fused).value_or(fused), {moments.rms_offset_m(), 0.0});
}

void make_fallback(DecisionRecord& record, std::string_view answered, const std::string& why) {
  record.explanation = "fallback (" + why + "); rules said " + std::string(answered) + " by " + record.rule;
  record.action = rules::Action::add;
  record.rule = "fallback";
  record.fallback = true;
}

// Whether `part` is a piece of the wall `whole` stands for, whatever its own direction says: at most half as long,
// its ends projected within `max_gap_m` of the whole's extent, and the part as a whole within `band_m` RMS of its
// line (the straightness an element keeps). A view of 0.3–0.7 m tilted by a 3σ 7° lies within 3 cm RMS of its
// wall but fails the direction gate; left alone, it stays as a stub beside the wall.
bool lies_within(const Element& part, const Element& whole, double band_m, double max_gap_m) {
  const fusion::LineSegment& w = whole.segment;
  if (part.support > 1 || part.segment.length_m() > 0.5 * w.length_m()) return false;
  const Eigen::Vector2d ends[2] = {part.segment.p0(), part.segment.p1()};
  double offsets[2];
  for (int k = 0; k < 2; ++k) {
    const double t = w.line.coordinate_along(ends[k]);
    if (t < w.t0_m - max_gap_m || t > w.t1_m + max_gap_m) return false;
    offsets[k] = w.line.signed_distance(ends[k]);
  }
  // RMS distance from the line of a segment whose ends lie at offsets a and b: sqrt((a² + ab + b²) / 3).
  const double a = offsets[0], b = offsets[1];
  return (a * a + a * b + b * b) / 3.0 <= band_m * band_m;
}

// Puts "element `from` lies on element `into`" to the rules (an observation of origin "element", observer: from's
// id); a merge answer joins them: fused line, union of extents, support and moments summed, `from` removed, one
// decision logged. A `piece` (lies_within) adds its moments and support but not its line: a view whose direction
// failed the gate would make the wall's covariance claim what the view does not know. Whether they were joined.
bool join_into(UpdateResult& result, std::int64_t into, std::int64_t from, const fusion::MatchResult& match, bool piece,
               const Observation& observation, std::int64_t observation_seq, const WorldOptions& options,
               const Decide& decide) {
  WorldState& state = result.state;
  const Element& keeper = state.elements.at(into);
  const Element& other = state.elements.at(from);
  rules::DecisionQuery q;
  q.observer = other.id();
  q.origin = "element";
  q.sensor = observation.sensor;
  q.rho_m = other.segment.line.rho_m;
  q.phi_rad = other.segment.line.phi_rad;
  q.length_m = other.segment.length_m();
  q.element_id = keeper.id();
  q.mahalanobis_sq = match.mahalanobis_sq;
  const rules::Decision decision = decide(q);
  if (rules::parse_action(decision.action) != rules::Action::merge) return false;
  DecisionRecord record;
  record.seq = ++state.last_decision_seq;
  record.observation_seq = observation_seq;
  record.index = -1;  // not about a segment of the request
  record.action = rules::Action::merge;
  record.rule = decision.rule;
  record.explanation = decision.explanation;
  record.fallback = decision.fallback;
  record.element = record.matched_element = keeper.id();
  record.mahalanobis_sq = match.mahalanobis_sq;
  record.observer = observation.observer;
  record.origin = "element";
  record.sensor = observation.sensor;
  record_observed(record, other.segment);
  record.before = line_numbers(keeper.segment.line);

  Element joined = keeper;
  joined.moments += other.moments;
  joined.segment = fused_and_refit(piece ? keeper.segment : fusion::fuse(keeper.segment, other.segment, options.fusion),
                                   joined.moments);
  joined.support += other.support;
  joined.updated_version = state.version;
  joined.updated_at_unix_s = observation.received_at_unix_s;
  record.after = line_numbers(joined.segment.line);
  state.elements.erase(from);
  result.changed_elements.erase(from);
  result.removed_elements.insert(from);
  state.elements.put(std::move(joined));
  result.changed_elements.insert(into);
  result.decisions.push_back(std::move(record));
  return true;
}

// After element `number` grew, other elements may now lie on it: two views of one wall that no single observation
// connected before. Each such neighbour (best first) is joined into it if the rules say merge (join_into); anything
// else leaves both. A neighbour that passes only as a piece of the grown element (lies_within) comes after every
// gated one. When the grown element is itself a piece of a longer one, it is joined into that one instead, and
// nothing more is asked for it.
void join_neighbours(UpdateResult& result, std::int64_t number, const Observation& observation,
                     std::int64_t observation_seq, const WorldOptions& options, const Decide& decide) {
  WorldState& state = result.state;
  std::set<std::int64_t> declined;
  for (std::size_t joins = 0; joins < options.max_joins_per_change;) {
    const Element& keeper = state.elements.at(number);
    const Box near = Box::of(keeper.segment, candidate_margin(options.join));
    std::optional<fusion::MatchResult> best;
    std::int64_t best_number = 0;
    bool keeper_is_piece = false, other_is_piece = false;
    for (const auto other_number : state.elements.near(near)) {
      const Element& other = state.elements.at(other_number);
      if (other_number == number || declined.count(other_number) || !Box::of(other.segment).overlaps(near) ||
          (keeper.moments + other.moments).rms_offset_m() > options.max_straightness_rms_m)
        continue;
      auto m = fusion::match_segment(keeper.segment, other.segment, options.join);
      bool keeper_piece = false, other_piece = false;
      const double band = options.max_straightness_rms_m, gap = options.join.max_gap_m;
      if (!m && ((other_piece = lies_within(other, keeper, band, gap)) ||
                 (keeper_piece = lies_within(keeper, other, band, gap)))) {
        constexpr double kAfterGated = 1e6;
        // Of the pieces, the longest first; of the walls the grown element is a piece of, the longest.
        m = fusion::MatchResult{0, fusion::mahalanobis_squared(keeper.segment.line, other.segment.line),
                                kAfterGated - other.segment.length_m()};
      }
      if (m && (!best || m->cost < best->cost)) {
        best = m;
        best_number = other_number;
        keeper_is_piece = keeper_piece;
        other_is_piece = other_piece;
      }
    }
    if (!best) return;
    if (keeper_is_piece) {
      if (join_into(result, best_number, number, *best, true, observation, observation_seq, options, decide)) return;
    } else if (join_into(result, number, best_number, *best, other_is_piece, observation, observation_seq, options,
                         decide)) {
      ++joins;
      continue;
    }
    declined.insert(best_number);
  }
}

}  // namespace

UpdateResult apply_observation(const WorldState& current, const Observation& observation, std::int64_t observation_seq,
                               const WorldOptions& options, const Decide& decide) {
  UpdateResult result{current, {}, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.last_observation_seq = observation_seq;

  for (std::size_t i = 0; i < observation.segments.size(); ++i) {
    const auto& seen = observation.segments[i].segment;
    // Matching runs against the map as changed by the earlier segments of the same request.
    const Candidates candidates = collect_candidates(state, seen, options);
    const auto match = fusion::best_match(candidates.segments, seen, options.match);
    const auto query = make_query(state, observation, seen, match, candidates);
    const rules::Decision decision = decide(query);

    DecisionRecord record;
    record.seq = ++state.last_decision_seq;
    record.observation_seq = observation_seq;
    record.index = static_cast<std::int64_t>(i);
    // The rules' atom becomes an Action here, once; an atom the server does not know is the fallback add.
    const auto action = rules::parse_action(decision.action);
    record.action = action.value_or(rules::Action::add);
    record.rule = decision.rule;
    record.explanation = decision.explanation;
    record.fallback = decision.fallback;
    record.element = query.element_id;
    record.object = query.object_id;
    record.matched_element = query.element_id;
    record.matched_object = query.object_id;
    if (match) record.mahalanobis_sq = match->mahalanobis_sq;
    record.observer = observation.observer;
    record.origin = observation.origin;
    record.sensor = observation.sensor;
    record_observed(record, seen);

    const CandidateRef* ref = match ? &candidates.refs[match->index] : nullptr;
    std::optional<std::int64_t> grown;  // the element a merge or add changed, whose neighbours are checked next
    if (!action || *action == rules::Action::prune || *action == rules::Action::trim) {
      make_fallback(record, decision.action, "action '" + decision.action + "' is not known to the server");
    } else if (record.action == rules::Action::merge && !ref) {
      make_fallback(record, decision.action, "merge needs a match");
    } else if (record.action == rules::Action::rigid_adjust && !(ref && ref->object)) {
      make_fallback(record, decision.action, "rigid_adjust needs a matched CAD object");
    }

    if (record.action == rules::Action::confirm) {
      if (ref && ref->object) {
        ObjectState object = state.objects[*ref->object];
        ++object.confirmations;
        object.updated_version = state.version;
        state.objects.put(*ref->object, std::move(object));
        result.changed_objects.insert(*ref->object);
      } else if (ref) {
        Element element = state.elements.at(ref->element);
        ++element.support;
        element.updated_version = state.version;
        element.updated_at_unix_s = observation.received_at_unix_s;
        state.elements.put(std::move(element));
        result.changed_elements.insert(ref->element);
      }
    } else if (record.action == rules::Action::merge && !ref->object) {
      Element element = state.elements.at(ref->element);
      record.before = line_numbers(element.segment.line);
      element.moments += fusion::SegmentMoments::of(seen);
      element.segment = fused_and_refit(fusion::fuse(element.segment, seen, options.fusion), element.moments);
      record.after = line_numbers(element.segment.line);
      ++element.support;
      element.updated_version = state.version;
      element.updated_at_unix_s = observation.received_at_unix_s;
      state.elements.put(std::move(element));
      result.changed_elements.insert(ref->element);
      grown = ref->element;
    } else if (record.action == rules::Action::merge) {
      // Merged into a CAD edge (e.g. a door that moves): the drawing stays as drawn; the observed state
      // becomes an element that starts from the fusion of the drawn edge and the observation.
      const auto& object = state.objects[*ref->object];
      const auto drawn = apriori_edge(object, ref->edge, options);
      record.before = line_numbers(drawn.line);
      Element element;
      element.number = state.next_element_number++;
      element.segment = fusion::fuse(drawn, seen, options.fusion);
      element.moments = fusion::SegmentMoments::of(seen);
      element.support = 2;
      element.origin = observation.origin;
      element.observer = observation.observer;
      element.created_version = element.updated_version = state.version;
      element.updated_at_unix_s = observation.received_at_unix_s;
      record.after = line_numbers(element.segment.line);
      record.element = element.id();
      result.changed_elements.insert(element.number);
      grown = element.number;
      state.elements.put(std::move(element));
    } else if (record.action == rules::Action::rigid_adjust) {
      ObjectState object = state.objects[*ref->object];
      try {
        record.before = pose_numbers(object.body);
        object.body = object.body.updated(ref->edge, seen.line, apriori_edge_noise(object, ref->edge, options));
        record.after = pose_numbers(object.body);
        ++object.adjustments;
        object.updated_version = state.version;
        state.objects.put(*ref->object, std::move(object));
        result.changed_objects.insert(*ref->object);
      } catch (const std::invalid_argument& e) {
        record.before.clear();
        make_fallback(record, decision.action, std::string("rigid update failed: ") + e.what());
      }
    }
    if (record.action == rules::Action::add) {
      Element element;
      element.number = state.next_element_number++;
      element.segment = seen;
      element.moments = fusion::SegmentMoments::of(seen);
      element.origin = observation.origin;
      element.observer = observation.observer;
      element.created_version = state.version;
      element.updated_version = state.version;
      element.updated_at_unix_s = observation.received_at_unix_s;
      record.element = element.id();
      record.object.reset();
      result.changed_elements.insert(element.number);
      grown = element.number;  // a view that missed the scan-line gate may still lie on an element
      state.elements.put(std::move(element));
    }
    result.decisions.push_back(std::move(record));
    if (grown) join_neighbours(result, *grown, observation, observation_seq, options, decide);
  }
  return result;
}

void apply_prune(UpdateResult& result, const std::vector<rules::PruneOrder>& orders, std::int64_t observation_seq,
                 const std::string& observer) {
  WorldState& state = result.state;
  for (const auto& order : orders) {
    const auto number = WorldState::element_number(order.element_id);
    if (!number) continue;
    const Element* pruned = state.elements.find(*number);
    if (!pruned) continue;
    DecisionRecord record;
    record.seq = ++state.last_decision_seq;
    record.observation_seq = observation_seq;
    record.index = -1;  // not about a segment of the request
    record.action = rules::Action::prune;
    record.rule = order.rule;
    record.explanation = order.explanation;
    record.element = order.element_id;
    record.observer = observer;
    record.origin = pruned->origin;
    record_observed(record, pruned->segment);
    record.before = line_numbers(pruned->segment.line);
    state.elements.erase(*number);
    result.changed_elements.erase(*number);
    result.removed_elements.insert(*number);
    result.decisions.push_back(std::move(record));
  }
}

rules::DecisionQuery DecisionRecord::query() const {
  rules::DecisionQuery q;
  q.observer = observer;
  q.rho_m = rho_m;
  q.phi_rad = phi_rad;
  q.length_m = (p1 - p0).norm();
  q.origin = origin;
  q.sensor = sensor;
  if (matched_element) {
    q.element_id = matched_element;
    q.object_id = matched_object;
    q.mahalanobis_sq = mahalanobis_sq.value_or(0.0);
  }
  return q;
}

UpdateResult apply_floor_plan(const WorldState& current, const apriori::FloorPlan& plan, const WorldOptions& options) {
  UpdateResult result{current, {}, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.plan_name = plan.name;
  state.objects = ObjectTable(make_objects(plan, options, state.version, current.placement));
  for (std::size_t i = 0; i < state.objects.size(); ++i) result.changed_objects.insert(i);
  return result;
}

std::vector<double> placement_numbers(const fusion::Similarity2D& placement, const Eigen::Matrix4d& cov) {
  std::vector<double> numbers{placement.x_m, placement.y_m, placement.theta_rad, placement.scale};
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) numbers.push_back(cov(r, c));
  return numbers;
}

UpdateResult apply_placement(const WorldState& current, const PlacementChange& change, std::int64_t observation_seq) {
  UpdateResult result{current, {}, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.last_observation_seq = observation_seq;
  state.placement = change.placement;
  state.placement_cov = change.cov;
  // A new table: a change of scale changes the edges without moving the poses, which ObjectTable::put would not
  // re-index.
  std::vector<ObjectState> objects;
  objects.reserve(current.objects.size());
  for (std::size_t i = 0; i < current.objects.size(); ++i) {
    objects.push_back(replaced(current.objects[i], current.placement, change.placement));
    objects.back().updated_version = state.version;
    result.changed_objects.insert(i);
  }
  state.objects = ObjectTable(std::move(objects));
  DecisionRecord d;
  d.seq = ++state.last_decision_seq;
  d.observation_seq = observation_seq;
  d.action = rules::Action::place;
  d.rule = change.rule;
  d.explanation = change.explanation;
  d.observer = change.observer;
  d.origin = "client";
  d.sensor = "none";
  d.before = placement_numbers(current.placement, current.placement_cov);
  d.after = placement_numbers(change.placement, change.cov);
  result.decisions.push_back(std::move(d));
  return result;
}

}  // namespace wm::world
