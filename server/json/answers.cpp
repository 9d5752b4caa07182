#include "server/json/answers.h"

#include "server/json/codec.h"

namespace wm::json_codec {

using nlohmann::json;

json decisions_json(const std::vector<world::DecisionRecord>& decisions) {
  json list = json::array();
  for (const auto& d : decisions) list.push_back(decision_json(d));
  return list;
}

json as_built_json(const world::WorldState& state, const world::AsBuiltReport& report) {
  json objects = json::array();
  for (const auto& entry : report.objects) {
    const auto& object = *entry.object;
    json item = {{"id", object.plan->id},
                 {"kind", object.plan->kind},
                 {"attributes", object.plan->attributes},
                 {"status", world::to_string(entry.status)},
                 {"confirmations", object.confirmations},
                 {"adjustments", object.adjustments}};
    if (const auto& d = entry.moved_by) {
      item["moved_by"] = {{"dx", d->dx_m},
                          {"dy", d->dy_m},
                          {"dtheta", d->dtheta_rad},
                          {"distance", d->distance_m},
                          {"sigma_xy", d->sigma_xy_m}};
    }
    objects.push_back(std::move(item));
  }
  json extra = json::array();
  for (const auto* element : report.not_in_plan) {
    const auto& s = element->segment;
    extra.push_back({{"id", element->id()},
                     {"p0", json::array({s.p0().x(), s.p0().y()})},
                     {"p1", json::array({s.p1().x(), s.p1().y()})},
                     {"length", s.length_m()},
                     {"support", element->support},
                     {"origin", element->origin},
                     {"source", element->origin}});  // "source": the name before "origin", kept for clients
  }
  return {{"plan", state.plan_name},
          {"version", state.version},
          {"summary",
           {{"objects", state.objects.size()},
            {"confirmed", report.confirmed},
            {"moved", report.moved},
            {"never_observed", report.never_observed},
            {"not_in_plan", report.not_in_plan.size()}}},
          {"objects", objects},
          {"not_in_plan", extra}};
}

}  // namespace wm::json_codec
