#include "server/world/plan_edit.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

namespace wm::world {
namespace {

/// A world point in an object's drawing frame, through the object as it stands now (its pose, the placement's
/// scale): what an edge cut at a world point must be cut at in the drawing.
Eigen::Vector2d to_object_frame(const ObjectState& object, const WorldState& state, const Eigen::Vector2d& world) {
  const auto& pose = object.body.pose();
  const double c = std::cos(pose.theta_rad), s = std::sin(pose.theta_rad);
  const Eigen::Vector2d d = world - Eigen::Vector2d(pose.x_m, pose.y_m);
  return Eigen::Vector2d(c * d.x() + s * d.y(), -s * d.x() + c * d.y()) / state.placement.scale;
}

/// Where edge k of a drawing is: (polyline index, segment index) or (nullopt, polygon side).
struct EdgePlace {
  std::optional<std::size_t> polyline;
  std::size_t index = 0;
};

EdgePlace place_of(const apriori::PlanObject& drawn, std::size_t k) {
  for (std::size_t p = 0; p < drawn.polylines.size(); ++p) {
    const std::size_t segments = drawn.polylines[p].empty() ? 0 : drawn.polylines[p].size() - 1;
    if (k < segments) return {p, k};
    k -= segments;
  }
  if (k < drawn.polygon.size()) return {std::nullopt, k};
  throw std::invalid_argument("plan_with_change: object '" + drawn.id + "' has no edge " + std::to_string(k));
}

/// Replaces edge k of `drawn` by the pieces [a, cut0] and [cut1, b] (either may be empty: cut0 == a drops the first).
/// Without cuts (both nullopt) the edge goes whole.
void cut_edge(apriori::PlanObject& drawn, std::size_t k, const std::optional<Eigen::Vector2d>& cut0,
              const std::optional<Eigen::Vector2d>& cut1) {
  const auto place = place_of(drawn, k);
  std::vector<Eigen::Vector2d> before, after;  // the points up to the edge's start, from its end
  if (place.polyline) {
    const auto& line = drawn.polylines[*place.polyline];
    before.assign(line.begin(), line.begin() + static_cast<std::ptrdiff_t>(place.index) + 1);
    after.assign(line.begin() + static_cast<std::ptrdiff_t>(place.index) + 1, line.end());
  } else {
    // A closed outline a → b → ... → a opened at the edge a → b: one polyline from b around to a, with the cut
    // pieces of the edge hung on its ends: [cut1, b, ..., a, cut0].
    const auto& ring = drawn.polygon;
    const std::size_t n = ring.size();
    std::vector<Eigen::Vector2d> joined;
    if (cut1) joined.push_back(*cut1);
    for (std::size_t i = 1; i <= n; ++i) joined.push_back(ring[(place.index + i) % n]);
    if (cut0) joined.push_back(*cut0);
    drawn.polygon.clear();
    drawn.polylines.push_back(std::move(joined));
    return;
  }
  if (cut0) before.push_back(*cut0);
  if (cut1) after.insert(after.begin(), *cut1);
  auto& lines = drawn.polylines;
  lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(*place.polyline));
  for (auto* piece : {&after, &before})
    if (piece->size() >= 2)
      lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(*place.polyline), std::move(*piece));
}

const ObjectState& object_named(const WorldState& state, const std::string& id) {
  const auto index = state.objects.index_of(id);
  if (!index) throw std::invalid_argument("plan_with_change: no object '" + id + "' in the plan");
  return state.objects[*index];
}

}  // namespace

apriori::FloorPlan current_plan(const WorldState& state) {
  apriori::FloorPlan plan;
  plan.name = state.plan_name;
  plan.objects.reserve(state.objects.size());
  for (const auto& object : state.objects) plan.objects.push_back(*object.plan);
  return plan;
}

apriori::FloorPlan plan_with_change(const WorldState& state, const Change& change, std::string* added_object_id) {
  auto plan = current_plan(state);
  const auto slot = [&plan](const std::string& id) {
    return std::find_if(plan.objects.begin(), plan.objects.end(), [&id](const auto& o) { return o.id == id; });
  };
  switch (change.kind) {
    case ChangeKind::wall_missing:
    case ChangeKind::wall_partly_missing: {
      const ObjectState& object = object_named(state, change.object_id);
      if (!change.edge || *change.edge >= object.body.edges().size())
        throw std::invalid_argument("plan_with_change: object '" + change.object_id + "' has no such edge");
      auto drawn = slot(change.object_id);
      std::optional<Eigen::Vector2d> cut0, cut1;
      if (change.kind == ChangeKind::wall_partly_missing) {
        // The stretch's ends in the drawing; the piece next to the edge's start (a) ends at the nearer one.
        const auto local = drawn->edges().at(*change.edge);  // a copy: edges() returns a temporary
        Eigen::Vector2d u = to_object_frame(object, state, change.p0), v = to_object_frame(object, state, change.p1);
        if ((u - local.p0).norm() > (v - local.p0).norm()) std::swap(u, v);
        const Eigen::Vector2d along = (local.p1 - local.p0).normalized();
        const double length = (local.p1 - local.p0).norm();
        // Pieces shorter than 1 mm are not drawn.
        if (along.dot(u - local.p0) > 1e-3) cut0 = local.p0 + std::clamp(along.dot(u - local.p0), 0.0, length) * along;
        if (along.dot(local.p1 - v) > 1e-3) cut1 = local.p0 + std::clamp(along.dot(v - local.p0), 0.0, length) * along;
      }
      cut_edge(*drawn, *change.edge, cut0, cut1);
      if (drawn->edges().empty()) plan.objects.erase(drawn);
      break;
    }
    case ChangeKind::object_gone:
      object_named(state, change.object_id);
      plan.objects.erase(slot(change.object_id));
      break;
    case ChangeKind::object_moved: {
      const ObjectState& object = object_named(state, change.object_id);
      slot(change.object_id)->pose = state.placement.inverse_transform_pose(object.body.pose());
      break;
    }
    case ChangeKind::new_wall: {
      const auto number = WorldState::element_number(change.element_id);
      const Element* element = number ? state.elements.find(*number) : nullptr;
      if (!element) throw std::invalid_argument("plan_with_change: no element '" + change.element_id + "' in the map");
      std::set<std::string> ids;
      for (const auto& o : plan.objects) ids.insert(o.id);
      std::string id = change.element_id + "-wall";
      for (int n = 2; ids.contains(id); ++n) id = change.element_id + "-wall-" + std::to_string(n);
      apriori::PlanObject wall;
      wall.id = id;
      wall.kind = "wall";
      wall.attributes = {"solid"};
      wall.polylines = {{state.placement.inverse_transform_point(element->segment.p0()),
                         state.placement.inverse_transform_point(element->segment.p1())}};
      plan.objects.push_back(std::move(wall));
      if (added_object_id) *added_object_id = id;
      break;
    }
  }
  return plan;
}

UpdateResult apply_plan_edit(const WorldState& current, const apriori::FloorPlan& plan, const WorldOptions& options,
                             const std::vector<std::int64_t>& remove_elements, std::int64_t observation_seq,
                             rules::Action action, const std::string& rule, const std::string& explanation,
                             const std::string& observer, const std::string& subject) {
  UpdateResult result{current, {}, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.last_observation_seq = observation_seq;
  state.plan_name = plan.name;
  auto fresh = make_objects(plan, options, state.version, current.placement);
  for (auto& object : fresh) {
    const auto index = current.objects.index_of(object.plan->id);
    if (!index) continue;
    const ObjectState& before = current.objects[*index];
    const auto& a = *before.plan;
    const auto& b = *object.plan;
    const bool same_drawing = a.kind == b.kind && a.attributes == b.attributes && a.polylines == b.polylines &&
                              a.polygon == b.polygon && a.pose.x_m == b.pose.x_m && a.pose.y_m == b.pose.y_m &&
                              a.pose.theta_rad == b.pose.theta_rad;
    if (same_drawing) {
      object = before;
    } else {
      object.confirmations = before.confirmations;  // still the same object, seen as often
    }
  }
  state.objects = ObjectTable(std::move(fresh));
  for (std::size_t i = 0; i < state.objects.size(); ++i) result.changed_objects.insert(i);
  for (const auto number : remove_elements)
    if (state.elements.erase(number)) result.removed_elements.insert(number);
  DecisionRecord d;
  d.seq = ++state.last_decision_seq;
  d.observation_seq = observation_seq;
  d.index = -1;  // not about a segment of a request
  d.action = action;
  d.rule = rule;
  d.explanation = explanation;
  d.observer = observer;
  d.origin = "plan";
  d.sensor = "none";
  if (state.find_object(subject) || current.find_object(subject))
    d.object = subject;
  else if (!subject.empty())
    d.element = subject;
  result.decisions.push_back(std::move(d));
  return result;
}

std::set<std::string> removed_objects(const WorldState& before, const WorldState& after) {
  std::set<std::string> ids;
  for (const auto& object : before.objects) ids.insert(object.plan->id);
  for (const auto& object : after.objects) ids.erase(object.plan->id);
  return ids;
}

}  // namespace wm::world
