#include "server/world/update.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <string_view>

#include "server/world/update_internal.h"

namespace wm::world {
namespace {

// Whether `seen` can be a view of `edge`, an edge of the rigid `object`: its ends within the edge's extent, up to
// the gap allowance, 3σ of where the object stands along the edge and `overrun_share` of its own length. A rigid
// object does not stretch, so a line much longer than the edge, or running far past its end (the wall a table
// stands against), is not that edge.
bool within_extent(const ObjectState& object, const fusion::LineSegment& edge, const fusion::LineSegment& seen,
                   double gap_m, double overrun_share) {
  const Eigen::Vector2d d = edge.line.direction();
  const Eigen::Vector2d middle = 0.5 * (edge.p0() + edge.p1());
  const auto& pose = object.body.pose();
  // Along the edge, the middle moves by d·δt + d·J(middle − t)·δθ.
  const Eigen::Vector3d j(d.x(), d.y(), d.dot(Eigen::Vector2d(-(middle.y() - pose.y_m), middle.x() - pose.x_m)));
  const double slack =
      gap_m + 3.0 * std::sqrt(std::max(0.0, j.dot(object.body.pose_cov() * j))) + overrun_share * seen.length_m();
  const double ta = edge.line.coordinate_along(seen.p0()), tb = edge.line.coordinate_along(seen.p1());
  return std::min(ta, tb) >= edge.t0_m - slack && std::max(ta, tb) <= edge.t1_m + slack;
}

// The extent an element keeps after taking in `seen`, a view tilted from its fused line by more than
// tilted_view_sigmas of the view's own direction σ: its extent before (`kept`, projected on the fused line), and
// the view only where it runs within tilted_view_offset_m of the fused line. A far view across a shallow bend (two
// facets of a curved wall a few degrees apart, too few returns on the short side for the scan-line split to find)
// gates onto the facet it mostly lies on; its line is fused in, but the part running off along the next facet is not
// that element's wall. nullopt: the view agrees with the line, and the fused extent stands.
std::optional<std::pair<double, double>> tilted_view_extent(const std::pair<double, double>& kept,
                                                            const fusion::LineSegment& fused,
                                                            const fusion::LineSegment& seen,
                                                            const WorldOptions& options) {
  const double angle = std::abs(std::remainder(seen.line.phi_rad - fused.line.phi_rad, std::numbers::pi));
  if (!(angle > options.tilted_view_sigmas * std::sqrt(std::max(0.0, seen.line.cov(1, 1))))) return std::nullopt;
  std::pair<double, double> extent = kept;
  if (const auto stretch = update_internal::stretch_within(fused.line, seen, options.tilted_view_offset_m)) {
    extent.first = std::min(extent.first, stretch->first);
    extent.second = std::max(extent.second, stretch->second);
  }
  return extent;
}

// The extent of `number` after taking in `seen`, cut where the view runs off its line onto another element's: a far
// view across a shallow bend (two facets of a curved wall a few degrees apart) gates onto the facet it mostly lies
// on, and its far end, lying on the next facet's element rather than this one's line, would carry this element along
// that facet. Cut at the two lines' crossing, never inside the extent it had before (`kept`, projected on the fused
// line). Elements crossing at a steep angle do not cut: past a T the view's end lies on this element's line, not on
// the crossing wall's.
std::pair<double, double> cut_at_neighbours(const WorldState& state, std::int64_t number,
                                            const std::pair<double, double>& kept, const fusion::LineSegment& fused,
                                            const fusion::LineSegment& seen, const WorldOptions& options) {
  const auto [old_t0, old_t1] = kept;
  double t0 = fused.t0_m, t1 = fused.t1_m;
  for (const Eigen::Vector2d& end : {seen.p0(), seen.p1()}) {
    const double t_end = fused.line.coordinate_along(end);
    if (t_end <= old_t1 && t_end >= old_t0) continue;  // this end does not stretch the element
    const double off_self = std::abs(fused.line.signed_distance(end));
    for (const auto other_number : state.elements.near(Box::of(seen))) {
      if (other_number == number) continue;
      const fusion::LineSegment& other = state.elements.at(other_number).segment;
      const double off_other = std::abs(other.line.signed_distance(end));
      const double t_on_other = other.line.coordinate_along(end);
      if (off_other >= off_self || off_other > options.tilted_view_offset_m ||
          t_on_other < other.t0_m - options.match.max_gap_m || t_on_other > other.t1_m + options.match.max_gap_m)
        continue;
      // Where the two lines cross: n₁·x = ρ₁, n₂·x = ρ₂.
      Eigen::Matrix2d normals;
      normals << fused.line.normal().transpose(), other.line.normal().transpose();
      if (std::abs(normals.determinant()) < 1e-6) continue;  // parallel: a join's business, not a corner
      const Eigen::Vector2d crossing = normals.inverse() * Eigen::Vector2d(fused.line.rho_m, other.line.rho_m);
      const double t_cross = fused.line.coordinate_along(crossing);
      if (t_end > old_t1 && t_cross < t1) t1 = std::max(old_t1, t_cross);
      if (t_end < old_t0 && t_cross > t0) t0 = std::min(old_t0, t_cross);
    }
  }
  return {t0, t1};
}

}  // namespace

namespace update_internal {

Candidates collect_candidates(const WorldState& state, const fusion::LineSegment& seen,
                              const std::optional<double>& seen_facing, const WorldOptions& options) {
  const Box near = Box::of(seen, candidate_margin(options.match));
  Candidates c;
  for (const auto& [i, k] : state.objects.edges_near(near)) {
    auto edge = apriori_edge(state.objects[i], k, options);
    if (!Box::of(edge).overlaps(near)) continue;
    if (is_rigid(state.objects[i]) &&
        !within_extent(state.objects[i], edge, seen, options.match.max_gap_m, options.rigid_overrun_share))
      continue;
    c.segments.push_back(std::move(edge));
    c.refs.push_back({i, k, 0});
  }
  const auto seen_moments = fusion::SegmentMoments::of(seen);
  const double straightness = straightness_allowance_m(seen, options);
  for (const auto number : state.elements.near(near)) {
    const Element& element = state.elements.at(number);
    if (!Box::of(element.segment).overlaps(near) || !faces_agree(element.facing_rad, seen_facing)) continue;
    // Taking `seen` in would bend the element: not the same straight wall, whatever the gate says.
    if ((element.moments + seen_moments).rms_offset_m() > straightness ||
        side_by_side(seen_moments, seen, element.moments, element.segment,
                     element.segment.length_m() < seen.length_m()
                         ? std::max(straightness, straightness_allowance_m(element.segment, options))
                         : straightness,
                     !element.both_ways))
      continue;
    c.segments.push_back(element.segment);
    c.refs.push_back({std::nullopt, 0, number});
  }
  return c;
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

void record_observed(DecisionRecord& record, const fusion::LineSegment& segment) {
  record.p0 = segment.p0();
  record.p1 = segment.p1();
  record.rho_m = segment.line.rho_m;
  record.phi_rad = segment.line.phi_rad;
  record.observed_cov = segment.line.cov;
}

DecisionRecord& remove_element(UpdateResult& result, std::int64_t number, std::string rule, std::string explanation,
                               const std::string& observer, std::int64_t observation_seq) {
  WorldState& state = result.state;
  const Element& removed = state.elements.at(number);
  DecisionRecord record;
  record.seq = ++state.last_decision_seq;
  record.observation_seq = observation_seq;
  record.index = -1;  // not about a segment of the request
  record.action = rules::Action::prune;
  record.rule = std::move(rule);
  record.explanation = std::move(explanation);
  record.element = removed.id();
  record.observer = observer;
  record.origin = removed.origin;
  record_observed(record, removed.segment);
  record.before = line_numbers(removed.segment.line);
  state.elements.erase(number);
  result.changed_elements.erase(number);
  result.removed_elements.insert(number);
  result.decisions.push_back(std::move(record));
  return result.decisions.back();
}

DecisionRecord& trim_element(UpdateResult& result, std::int64_t number, const fusion::LineSegment& kept,
                             std::string rule, std::string explanation, const TrimSource& source) {
  WorldState& state = result.state;
  Element trimmed = state.elements.at(number);
  const Eigen::Vector2d a = trimmed.segment.p0(), b = trimmed.segment.p1();
  trimmed.segment = kept;
  trimmed.updated_version = state.version;
  if (source.at_unix_s) trimmed.updated_at_unix_s = *source.at_unix_s;
  DecisionRecord record;
  record.seq = ++state.last_decision_seq;
  record.observation_seq = source.observation_seq;
  record.index = -1;  // not about a segment of a request
  record.action = rules::Action::trim;
  record.rule = std::move(rule);
  record.explanation = std::move(explanation);
  record.element = trimmed.id();
  record.observer = source.observer;
  record.origin = source.origin;
  record.sensor = source.sensor;
  record_observed(record, kept);
  record.before = {a.x(), a.y(), b.x(), b.y()};
  record.after = {record.p0.x(), record.p0.y(), record.p1.x(), record.p1.y()};
  result.decisions.push_back(std::move(record));
  result.changed_elements.insert(number);
  state.elements.put(std::move(trimmed));
  return result.decisions.back();
}

void make_fallback(DecisionRecord& record, std::string_view answered, const std::string& why) {
  record.explanation = "fallback (" + why + "); rules said " + std::string(answered) + " by " + record.rule;
  record.action = rules::Action::add;
  record.rule = "fallback";
  record.fallback = true;
}

std::int64_t add_element(UpdateResult& result, const ObservedSegment& seen, const Observation& observation) {
  WorldState& state = result.state;
  Element element;
  element.number = state.next_element_number++;
  element.segment = seen.segment;
  element.moments = fusion::SegmentMoments::of(seen.segment);
  element.facing_rad = seen.facing_rad;
  element.origin = observation.origin;
  element.observer = observation.observer;
  element.created_version = state.version;
  element.updated_version = state.version;
  element.updated_at_unix_s = observation.received_at_unix_s;
  const std::int64_t number = element.number;
  result.changed_elements.insert(number);
  state.elements.put(std::move(element));
  return number;
}

}  // namespace update_internal

namespace {

using namespace update_internal;

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

std::string pose_text(const fusion::Pose2D& pose) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.3f, %.3f, %.4f)", pose.x_m, pose.y_m, pose.theta_rad);
  return text;
}

}  // namespace

using namespace update_internal;

std::string continuation_note(std::int64_t number) {
  return "a continuation of " + element_id(number) + " through sparse grazing returns";
}

double facing_toward(const fusion::LineSegment& segment, const Eigen::Vector2d& viewpoint) {
  const double phi = segment.line.phi_rad;
  return segment.line.signed_distance(viewpoint) >= 0 ? phi
                                                      : std::remainder(phi + std::numbers::pi, 2 * std::numbers::pi);
}

bool faces_agree(const std::optional<double>& a, const std::optional<double>& b) {
  return !a || !b || std::cos(*a - *b) > 0;
}

UpdateResult apply_observation(const WorldState& current, const Observation& observation, std::int64_t observation_seq,
                               const WorldOptions& options, const Decide& decide) {
  UpdateResult result{current, {}, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.last_observation_seq = observation_seq;

  const FoundByShape found = find_moved_objects(current, observation, options);
  std::map<std::size_t, PendingRigid> pending;  // by object index
  const bool grid_line = observation.origin == "grid";
  std::set<std::int64_t> grid_surfaces;  // the elements a grid line confirmed, merged into or became

  for (std::size_t i = 0; i < observation.segments.size(); ++i) {
    const auto& seen = observation.segments[i].segment;
    // Matching runs against the map as changed by the earlier segments of the same request (rigid objects move
    // once, after the last segment).
    const auto continues = observation.segments[i].continues;
    Candidates candidates;
    if (!continues) {
      candidates = collect_candidates(state, seen, observation.segments[i].facing_rad, options);
    } else if (state.elements.contains(*continues)) {  // (an earlier segment may have joined it into another)
      candidates.segments.push_back(state.elements.at(*continues).segment);
      candidates.refs.push_back({std::nullopt, 0, *continues});
    }
    auto match = fusion::best_match(candidates.segments, seen, options.match);
    if (grid_line && !found.ref[i] && !(match && candidates.refs[match->index].object)) {
      // A grid line is known to a cell across (and a short one fitted near a corner may lean by a degree): on a
      // wall the scans mapped it can fall outside that element's segment gate, whose σ are the scans' own.
      if (const auto on = grid_line_on_element(state, seen, options.grid_lines)) {
        std::size_t k = 0;
        while (k < candidates.refs.size() && (candidates.refs[k].object || candidates.refs[k].element != *on)) ++k;
        if (k == candidates.refs.size()) {
          candidates.segments.push_back(state.elements.at(*on).segment);
          candidates.refs.push_back({std::nullopt, 0, *on});
        }
        match = fusion::MatchResult{k, fusion::mahalanobis_squared(candidates.segments[k].line, seen.line), 0.0};
      }
    }
    if (found.ref[i]) {
      // A view of a carried object: matched to its edge where its shape was found.
      const CandidateRef& f = *found.ref[i];
      const ObjectState& object = state.objects[*f.object];
      const fusion::RigidObject there(found.pose.at(*f.object), object.body.pose_cov(), object.body.edges());
      candidates.segments.push_back(there.world_edge(f.edge, apriori_edge_noise(object, f.edge, options)));
      candidates.refs.push_back(f);
      match = fusion::MatchResult{candidates.segments.size() - 1,
                                  fusion::mahalanobis_squared(candidates.segments.back().line, seen.line), 0.0};
    }
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
    if (found.ref[i])
      record.explanation +=
          " (matched by the object's shape, found at " + pose_text(found.pose.at(*found.ref[i]->object)) + ")";
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

    // A continuation only stretches (or confirms) the element it continues: it carries no line of its own. Its
    // decisions say what they are, whatever the rules' explanation.
    if (continues) {
      if (record.action != rules::Action::confirm && record.action != rules::Action::ignore &&
          !(record.action == rules::Action::merge && ref && !ref->object && ref->element == *continues)) {
        record.explanation += " (not applied: a continuation only stretches the element it continues)";
        record.action = rules::Action::ignore;
        ref = nullptr;
      }
      record.explanation += " [" + continuation_note(*continues) + "]";
    }

    // A grid line merged into an element that scans or a client made gives it its support and its extent, not its
    // line: the element's line, covariance and moments stay what its own views say (the grid knows the surface to
    // a cell, those views to a centimetre or two). The grid line's ends lie on the surface's ends to half a cell,
    // and an end past a wall the grid saw is cut back to it after the last line (cut_at_grid_surfaces).
    const bool grid_on_measured = grid_line && ref && !ref->object && !made_by_grid(state.elements.at(ref->element));
    if (grid_line && ref && !ref->object && record.action == rules::Action::confirm) grid_surfaces.insert(ref->element);

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
      if (grid_on_measured) {
        if (const auto stretch = stretch_within(element.segment.line, seen, options.grid_lines.extend_offset_m)) {
          element.segment.t0_m = std::min(element.segment.t0_m, stretch->first);
          element.segment.t1_m = std::max(element.segment.t1_m, stretch->second);
        }
        record.explanation += " (a grid line on an element from scans or a client: its extent taken in, not its line)";
      } else if (continues) {
        if (const auto stretch = stretch_within(element.segment.line, seen, options.tilted_view_offset_m)) {
          element.segment.t0_m = std::min(element.segment.t0_m, stretch->first);
          element.segment.t1_m = std::max(element.segment.t1_m, stretch->second);
        }
        record.explanation += " (its extent taken in, not its line)";
      } else {
        const fusion::LineSegment before = element.segment;
        element.moments += fusion::SegmentMoments::of(seen);
        element.segment = fused_and_refit(fusion::fuse(element.segment, seen, options.fusion), element.moments);
        const double ta = element.segment.line.coordinate_along(before.p0()),
                     tb = element.segment.line.coordinate_along(before.p1());
        const std::pair kept{std::min(ta, tb), std::max(ta, tb)};  // the extent before, on the fused line
        if (const auto extent = tilted_view_extent(kept, element.segment, seen, options)) {
          element.segment.t0_m = extent->first;
          element.segment.t1_m = extent->second;
        }
        const auto cut = cut_at_neighbours(state, ref->element, kept, element.segment, seen, options);
        element.segment.t0_m = cut.first;
        element.segment.t1_m = cut.second;
        element.segment = stop_at_corners(state, ref->element, kept, element.segment, options);
        // An element that faces both ways keeps doing so; one whose side was not known learns it.
        if (!element.facing_rad && !element.both_ways) element.facing_rad = observation.segments[i].facing_rad;
      }
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
      element.facing_rad = observation.segments[i].facing_rad;
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
      // Deferred: every line of this observation on the object goes into one joint update (apply_rigid).
      PendingRigid& p = pending[*ref->object];
      p.lines.push_back({ref->edge, seen.line, apriori_edge_noise(state.objects[*ref->object], ref->edge, options)});
      p.records.push_back(result.decisions.size());
      p.segments.push_back(i);
      p.by_shape |= found.ref[i].has_value();
    }
    if (record.action == rules::Action::add) {
      const auto number = add_element(result, observation.segments[i], observation);
      record.element = element_id(number);
      record.object.reset();
      grown = number;  // a view that missed the scan-line gate may still lie on an element
    }
    result.decisions.push_back(std::move(record));
    if (grown) join_neighbours(result, *grown, observation, observation_seq, options, decide);
    if (grown && state.elements.contains(*grown)) cut_at_corners(result, *grown, observation, observation_seq, options);
    // The element a grid line merged into or became, unless a join took it into another one: a surface the grid saw.
    if (grid_line && grown && state.elements.contains(*grown)) grid_surfaces.insert(*grown);
  }
  for (const auto& [index, p] : pending)
    apply_rigid(result, index, p, found, observation, observation_seq, options, decide);
  if (grid_line) cut_at_grid_surfaces(result, grid_surfaces, observation, observation_seq, options.grid_lines);
  return result;
}

void apply_prune(UpdateResult& result, const std::vector<rules::PruneOrder>& orders, std::int64_t observation_seq,
                 const std::string& observer) {
  WorldState& state = result.state;
  for (const auto& order : orders) {
    const auto number = WorldState::element_number(order.element_id);
    if (!number) continue;
    if (!state.elements.contains(*number)) continue;
    remove_element(result, *number, order.rule, order.explanation, observer, observation_seq).element =
        order.element_id;
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
