// CAD objects and observed elements: lists, one by id, and the decisions about each.
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/json/answers.h"
#include "server/world/as_built.h"

namespace wm::api {
namespace {

// Every decision about an object or element ever logged (deleted elements keep their history).
constexpr std::size_t kMaxHistory = 10000;

nlohmann::json history(const Call& call, std::vector<world::DecisionRecord> rows, bool exists) {
  const auto& id = call.param;
  if (rows.empty() && !exists)
    throw ApiError(404, "not_found", "no element or object '" + id + "' and no decision about it");
  return {{"id", id}, {"exists", exists}, {"decisions", json_codec::decisions_json(rows)}};
}

}  // namespace

Response get_objects(const Call& call) {
  const auto snap = call.world.map.snapshot();
  nlohmann::json list = nlohmann::json::array();
  for (const auto& o : snap->objects) list.push_back(json_codec::object_json(o, call.world.map.world_options()));
  return json_response(call.request, {{"version", snap->version}, {"objects", list}});
}

Response get_object(const Call& call) {
  const auto snap = call.world.map.snapshot();
  const auto* object = snap->find_object(call.param);
  if (!object) throw ApiError(404, "not_found", "no object '" + call.param + "' in the floor plan");
  return json_response(call.request, json_codec::object_json(*object, call.world.map.world_options()));
}

Response get_object_history(const Call& call) {
  // An object's history includes the decisions about each of its edges ("table-1/2").
  const auto snap = call.world.map.snapshot();
  const auto index = snap->objects.index_of(call.param);
  auto answer = history(call, call.world.map.object_decisions(call.param, kMaxHistory), index.has_value());
  // What the grid says of it now, and the rules' verdicts: how much of a missing wall was seen through.
  if (index) {
    const auto evidence = call.world.map.plan_report();
    const auto report = world::as_built_report(*snap, evidence.get());
    answer["as_built"] = json_codec::object_as_built_json(report.objects[*index], *index, evidence.get());
  }
  return json_response(call.request, answer);
}

Response get_elements(const Call& call) {
  const auto snap = call.world.map.snapshot();
  nlohmann::json list = nlohmann::json::array();
  for (const auto& [number, e] : snap->elements) list.push_back(json_codec::element_json(e));
  return json_response(call.request, {{"version", snap->version}, {"elements", list}});
}

Response get_element(const Call& call) {
  const auto snap = call.world.map.snapshot();
  const auto* element = snap->find_element(call.param);
  if (!element) throw ApiError(404, "not_found", "no element '" + call.param + "' in the map");
  return json_response(call.request, json_codec::element_json(*element));
}

Response get_element_history(const Call& call) {
  const bool exists = call.world.map.snapshot()->find_element(call.param) != nullptr;
  return json_response(call.request, history(call, call.world.map.decisions(0, kMaxHistory, call.param), exists));
}

}  // namespace wm::api
