#include "server/json/answers.h"

#include "server/json/codec.h"

namespace wm::json_codec {

using nlohmann::json;

json decisions_json(const std::vector<world::DecisionRecord>& decisions) {
  json list = json::array();
  for (const auto& d : decisions) list.push_back(decision_json(d));
  return list;
}

namespace {

json point(const Eigen::Vector2d& p) { return json::array({p.x(), p.y()}); }

json displacement_json(const world::Displacement& d) {
  return {
      {"dx", d.dx_m}, {"dy", d.dy_m}, {"dtheta", d.dtheta_rad}, {"distance", d.distance_m}, {"sigma_xy", d.sigma_xy_m}};
}

json evidence_json(const world::EdgeEvidence& e) {
  json stretches = json::array();
  for (const auto& s : e.seen_through_stretches)
    stretches.push_back(
        {{"s0", s.s0_m}, {"s1", s.s1_m}, {"beams_through", s.beams_through}, {"beams_ended", s.beams_ended}});
  return {{"edge", e.edge},
          {"length", e.length_m},
          {"backed", e.backed},
          {"seen_through", e.seen_through},
          {"observed", e.observed},
          {"beams_through", e.beams_through},
          {"beams_ended", e.beams_ended},
          {"seen_through_stretches", stretches}};
}

}  // namespace

json object_as_built_json(const world::ObjectAsBuilt& entry, std::size_t index, const world::PlanReport* evidence) {
  const auto& object = *entry.object;
  json item = {{"id", object.plan->id},
               {"kind", object.plan->kind},
               {"attributes", object.plan->attributes},
               {"status", world::to_string(entry.status)},
               {"confirmations", object.confirmations},
               {"adjustments", object.adjustments}};
  if (const auto& d = entry.moved_by) item["moved_by"] = displacement_json(*d);
  if (evidence) {
    json edges = json::array();
    for (std::size_t k = 0; k < object.body.edges().size(); ++k)
      if (const auto* e = evidence->find(index, k)) edges.push_back(evidence_json(*e));
    if (!edges.empty()) item["edges"] = std::move(edges);
  }
  if (!entry.verdicts.empty()) {
    json verdicts = json::array();
    for (const auto* v : entry.verdicts) {
      json verdict = {{"verdict", v->verdict}, {"rule", v->rule}, {"explanation", v->explanation}};
      if (v->edge && *v->edge < object.body.edges().size()) {
        const auto segment = object.body.world_edge(*v->edge, Eigen::Matrix2d::Zero());
        const double length = segment.length_m();
        const Eigen::Vector2d a = segment.p0(), b = segment.p1();
        verdict["edge"] = world::edge_id(object.plan->id, *v->edge);
        verdict["s0"] = v->stretch.s0_m;
        verdict["s1"] = v->stretch.s1_m;
        verdict["p0"] = point(a + (v->stretch.s0_m / length) * (b - a));
        verdict["p1"] = point(a + (v->stretch.s1_m / length) * (b - a));
      }
      verdicts.push_back(std::move(verdict));
    }
    item["verdicts"] = std::move(verdicts);
  }
  return item;
}

json as_built_json(const world::WorldState& state, const world::AsBuiltReport& report,
                   const world::PlanReport* evidence) {
  json objects = json::array();
  for (std::size_t i = 0; i < report.objects.size(); ++i)
    objects.push_back(object_as_built_json(report.objects[i], i, evidence));
  json extra = json::array();
  for (const auto* element : report.not_in_plan) {
    const auto& s = element->segment;
    extra.push_back({{"id", element->id()},
                     {"p0", point(s.p0())},
                     {"p1", point(s.p1())},
                     {"length", s.length_m()},
                     {"support", element->support},
                     {"origin", element->origin},
                     {"source", element->origin}});  // "source": the name before "origin", kept for clients
  }
  json answer = {{"plan", state.plan_name},
                 {"version", state.version},
                 {"summary",
                  {{"objects", state.objects.size()},
                   {"confirmed", report.confirmed},
                   {"moved", report.moved},
                   {"never_observed", report.never_observed},
                   {"missing", report.missing},
                   {"partly_missing", report.partly_missing},
                   {"gone", report.gone},
                   {"not_in_plan", report.not_in_plan.size()}}},
                 {"objects", objects},
                 {"not_in_plan", extra}};
  if (evidence) answer["grid_revision"] = evidence->grid_revision;
  return answer;
}

json change_json(const world::Change& change) {
  json item = {{"id", change.id},
               {"key", change.key},
               {"kind", world::to_string(change.kind)},
               {"p0", point(change.p0)},
               {"p1", point(change.p1)},
               {"length", change.length_m},
               {"confidence", change.confidence},
               {"rule", change.rule},
               {"explanation", change.explanation}};
  if (!change.object_id.empty()) item["object"] = change.object_id;
  if (change.edge) {
    item["edge"] = world::edge_id(change.object_id, *change.edge);
    item["stretch"] = {change.stretch.s0_m, change.stretch.s1_m};
  }
  if (!change.element_id.empty()) {
    item["element"] = change.element_id;
    item["support"] = change.support;
  }
  if (change.evidence)
    item["evidence"] = {{"backed", change.evidence->backed},
                        {"seen_through", change.evidence->seen_through},
                        {"observed", change.evidence->observed},
                        {"length", change.evidence->length_m},
                        {"beams_through", change.evidence->beams_through},
                        {"beams_ended", change.evidence->beams_ended}};
  if (change.moved_by) item["moved_by"] = displacement_json(*change.moved_by);
  return item;
}

json changes_json(const world::WorldState& state, const world::PlanReport& evidence,
                  const std::vector<world::Change>& changes) {
  json list = json::array();
  for (const auto& change : changes) list.push_back(change_json(change));
  return {{"version", state.version}, {"grid_revision", evidence.grid_revision}, {"changes", list}};
}

}  // namespace wm::json_codec
