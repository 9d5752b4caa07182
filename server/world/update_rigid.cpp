// Rigid (not_deformable) objects: found again by their shape when carried beyond their gate, and moved by
// the lines the rules sent to rigid_adjust.
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

namespace wm::world::update_internal {
namespace {

// How far a rigid object may have been carried and still be found by its shape (its centroid's move) [m], and
// the bounds that keep the search cheap: objects per observation, segments per object.
constexpr double kShapeSearchM = 1.0;
constexpr std::size_t kShapeObjects = 4;
constexpr std::size_t kShapeSegments = 24;

double distance_to_segment(const Eigen::Vector2d& p, const fusion::LineSegment& s) {
  const Eigen::Vector2d a = s.p0(), d = s.p1() - a;
  const double len2 = d.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

// After an object moved (found by its shape where it was carried, or adjusted by its views): the elements views of
// it became (seen one side at a time before two sides showed in one scan, or a short view its few returns tilted
// past the edge's gate) lie on its edges now. They are views of the object, not walls: each goes with a prune
// decision (rule object_found). An element lies on an edge when it faces out of the object (or its facing is not
// known), both its ends are within 5 cm of the edge's line, its direction within 5° (or, for one shorter than
// 0.57 m, within atan(5 cm / its length): a 0.37 m view of a table's end turned 6° by its few returns), and at least
// 80 % of its length within the edge's extent plus 10 cm: views that took in a corner's mixed returns make an element
// a little longer than the side, while a wall that runs on past the object along the same line lies mostly beyond it.
void absorb_elements(UpdateResult& result, std::size_t index, bool by_shape, const Observation& observation,
                     std::int64_t observation_seq) {
  constexpr double kOffsetM = 0.05, kAngleRad = 0.0873, kBeyondM = 0.10, kOnShare = 0.8;
  WorldState& state = result.state;
  const ObjectState& object = state.objects[index];
  std::vector<fusion::LineSegment> edges;
  Box box{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::lowest(),
          std::numeric_limits<double>::lowest()};
  for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
    edges.push_back(object.body.world_edge(k, Eigen::Matrix2d::Zero()));
    const Box b = Box::of(edges.back(), kBeyondM);
    box = {std::min(box.x0, b.x0), std::min(box.y0, b.y0), std::max(box.x1, b.x1), std::max(box.y1, b.y1)};
  }
  const Eigen::Vector2d centre = object.body.pose().transform_point(object.body.local_centroid());
  for (const auto number : state.elements.near(box)) {
    const Element* element = state.elements.find(number);
    if (!element) continue;
    const auto& seg = element->segment;
    const bool on_an_edge = std::any_of(edges.begin(), edges.end(), [&](const fusion::LineSegment& edge) {
      // A view of the object's side was seen from outside it: a wall the object stands against, seen from the room
      // beside it, faces the other way.
      const Eigen::Vector2d n = edge.line.normal();
      const double outward =
          n.dot(0.5 * (edge.p0() + edge.p1()) - centre) >= 0 ? std::atan2(n.y(), n.x()) : std::atan2(-n.y(), -n.x());
      if (!faces_agree(element->facing_rad, outward)) return false;
      const double angle = std::abs(std::remainder(seg.line.phi_rad - edge.line.phi_rad, std::numbers::pi));
      if (angle > std::max(kAngleRad, std::atan2(kOffsetM, seg.length_m()))) return false;
      for (const Eigen::Vector2d& p : {seg.p0(), seg.p1()})
        if (std::abs(edge.line.signed_distance(p)) > kOffsetM) return false;
      const double ta = edge.line.coordinate_along(seg.p0()), tb = edge.line.coordinate_along(seg.p1());
      const double lo = std::min(ta, tb), hi = std::max(ta, tb);
      const double on = std::min(hi, edge.t1_m + kBeyondM) - std::max(lo, edge.t0_m - kBeyondM);
      return on >= kOnShare * (hi - lo);
    });
    if (!on_an_edge) continue;
    remove_element(result, number, "object_found",
                   element->id() + " lies on an edge of " + object.plan->id +
                       (by_shape ? ", found again by its shape where it was carried: a view of it, not a wall"
                                 : ", where its last adjustment placed it: a view of it, not a wall"),
                   observation.observer, observation_seq)
        .object = object.plan->id;
  }
}

}  // namespace

FoundByShape find_moved_objects(const WorldState& state, const Observation& observation, const WorldOptions& options) {
  FoundByShape found;
  const std::size_t n = observation.segments.size();
  found.ref.resize(n);
  if (n < 2 || state.objects.empty()) return found;
  Box box{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::lowest(),
          std::numeric_limits<double>::lowest()};
  for (const auto& s : observation.segments) {
    const Box b = Box::of(s.segment);
    box = {std::min(box.x0, b.x0), std::min(box.y0, b.y0), std::max(box.x1, b.x1), std::max(box.y1, b.y1)};
  }
  box = {box.x0 - kShapeSearchM, box.y0 - kShapeSearchM, box.x1 + kShapeSearchM, box.y1 + kShapeSearchM};
  // Nearest objects first: their centroid's distance to the closest segment.
  std::vector<std::pair<double, std::size_t>> objects;
  for (const auto& [i, k] : state.objects.edges_near(box)) {
    if ((!objects.empty() && objects.back().second == i) || !is_rigid(state.objects[i])) continue;
    const auto& body = state.objects[i].body;
    const Eigen::Vector2d centre = body.pose().transform_point(body.local_centroid());
    double nearest = std::numeric_limits<double>::max();
    for (const auto& s : observation.segments) nearest = std::min(nearest, distance_to_segment(centre, s.segment));
    objects.emplace_back(nearest, i);
  }
  std::sort(objects.begin(), objects.end());
  if (objects.size() > kShapeObjects) objects.resize(kShapeObjects);

  // What each segment matches in the map as it is (asked only of segments near a searched object, once): nullopt
  // nothing, else the candidate's object index, kElement for an element.
  constexpr std::size_t kElement = std::numeric_limits<std::size_t>::max();
  std::vector<std::optional<std::optional<std::size_t>>> matched(n);
  std::vector<std::int64_t> matched_element(n, 0);  // the element number when matched[i] is kElement
  for (const auto& [nearest, index] : objects) {
    const auto& body = state.objects[index].body;
    const Eigen::Vector2d centre = body.pose().transform_point(body.local_centroid());
    double radius = 0.0;
    for (const auto& e : body.edges()) {
      radius = std::max(radius, (body.pose().transform_point(e.p0) - centre).norm());
      radius = std::max(radius, (body.pose().transform_point(e.p1) - centre).norm());
    }
    std::vector<std::size_t> group;
    bool any_unmatched = false;
    for (std::size_t i = 0; i < n; ++i) {
      const auto& seen = observation.segments[i].segment;
      if (found.ref[i] || distance_to_segment(centre, seen) > kShapeSearchM + radius) continue;
      if (!matched[i]) {
        const Candidates candidates = collect_candidates(state, seen, observation.segments[i].facing_rad, options);
        const auto m = fusion::best_match(candidates.segments, seen, options.match);
        matched[i] = !m ? std::optional<std::size_t>{} : candidates.refs[m->index].object.value_or(kElement);
        if (m && !candidates.refs[m->index].object) matched_element[i] = candidates.refs[m->index].element;
      }
      const auto& what = *matched[i];
      // A view matched to an element that lies on the object's reach may be a view of the carried object whose
      // earlier views, seen one side at a time, became elements before two sides showed in one scan.
      bool element_near = false;
      if (what && *what == kElement)
        if (const Element* e = state.elements.find(matched_element[i]))
          element_near = distance_to_segment(centre, e->segment) <= radius + kShapeSearchM;
      if (what && *what != index && !element_near) continue;  // a view of something else
      any_unmatched |= !what || element_near;
      group.push_back(i);
    }
    if (group.size() < 2 || !any_unmatched) continue;
    std::stable_sort(group.begin(), group.end(), [&](std::size_t a, std::size_t b) {
      return observation.segments[a].segment.length_m() > observation.segments[b].segment.length_m();
    });
    if (group.size() > kShapeSegments) group.resize(kShapeSegments);
    std::vector<fusion::LineSegment> segments;
    for (const auto i : group) segments.push_back(observation.segments[i].segment);
    fusion::ShapeFitOptions fit_options;
    fit_options.max_shift_m = kShapeSearchM;
    const auto fit = fusion::find_by_shape(body, segments, fit_options);
    if (!fit) continue;
    bool explains_unmatched = false;
    for (std::size_t g = 0; g < group.size(); ++g)
      explains_unmatched |= fit->edge_of[g] && (!*matched[group[g]] || **matched[group[g]] == kElement);
    if (!explains_unmatched) continue;
    for (std::size_t g = 0; g < group.size(); ++g)
      if (fit->edge_of[g]) found.ref[group[g]] = CandidateRef{index, *fit->edge_of[g], 0};
    found.pose[index] = fit->pose;
  }
  return found;
}

void apply_rigid(UpdateResult& result, std::size_t index, const PendingRigid& pending, const FoundByShape& found,
                 const Observation& observation, std::int64_t observation_seq, const WorldOptions& options,
                 const Decide& decide) {
  WorldState& state = result.state;
  ObjectState object = state.objects[index];
  fusion::RigidObject body = object.body;
  fusion::RigidUpdateOptions how;
  if (const auto at = found.pose.find(index); pending.by_shape && at != found.pose.end()) {
    body = body.with_move_allowed(at->second);
    how.start = at->second;
  }
  try {
    const auto before = pose_numbers(object.body);
    object.body = body.updated(pending.lines, how);
    const auto after = pose_numbers(object.body);
    for (const auto r : pending.records) {
      result.decisions[r].before = before;
      result.decisions[r].after = after;
    }
    object.adjustments += static_cast<std::int64_t>(pending.lines.size());
    object.updated_version = state.version;
    state.objects.put(index, std::move(object));
    result.changed_objects.insert(index);
    absorb_elements(result, index, pending.by_shape, observation, observation_seq);
  } catch (const std::invalid_argument& e) {
    for (std::size_t j = 0; j < pending.records.size(); ++j) {
      DecisionRecord& record = result.decisions[pending.records[j]];
      make_fallback(record, rules::wire_name(rules::Action::rigid_adjust),
                    std::string("rigid update failed: ") + e.what());
      record.object.reset();
      const auto number = add_element(result, observation.segments[pending.segments[j]], observation);
      record.element = element_id(number);
      join_neighbours(result, number, observation, observation_seq, options, decide);
    }
  }
}

}  // namespace wm::world::update_internal
