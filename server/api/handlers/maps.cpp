// The maps one server holds: GET/POST /api/v1/maps, GET/DELETE /api/v1/maps/{map}. Each map's own resources are
// today's routes under /api/v1/maps/{map}/ (split off in the router); the default map's are also today's routes.
#include <algorithm>
#include <string>
#include <vector>

#include "apriori/import/rmf_import.h"
#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/map_scope.h"
#include "server/api/request.h"
#include "server/api/response.h"

namespace wm::api {
namespace {

const std::string kIdRule(service::kMapIdRule);

// What a list shows of one map: where it is and how far it has come.
nlohmann::json map_summary(const std::string& id, const service::WorldPorts& world) {
  const auto state = world.map.snapshot();
  return {{"id", id},
          {"default", id == service::kDefaultMapId},
          {"href", id == service::kDefaultMapId ? "/api/v1" : "/api/v1/maps/" + id},
          {"version", state->version},
          {"plan_name", state->plan_name},
          {"objects", state->objects.size()},
          {"elements", state->elements.size()},
          {"observations", state->last_observation_seq},
          {"robots", world.robots.robots().size()}};
}

// A map of the registry. @throw ApiError 404 when there is none.
std::shared_ptr<service::MapInstance> find_map(const Call& call, const std::string& id) {
  auto map = call.maps ? call.maps->find(id) : nullptr;
  if (!map) throw map_not_found(id);
  return map;
}

// The id in the path, checked before anything is looked up: "a/b" (a deeper path no route has) is refused here too.
std::string path_map_id(const Call& call) {
  if (!service::valid_map_id(call.param)) throw bad_request("map", kIdRule);
  return call.param;
}

}  // namespace

Response get_maps(const Call& call) {
  nlohmann::json list = nlohmann::json::array();
  // The default map is the one this call's ports reach (GET /api/v1/maps is no map's own route).
  list.push_back(map_summary(std::string(service::kDefaultMapId), call.world));
  if (call.cluster) {
    // Every map of the cluster: this node's with their summary, the others with the node that serves them (their
    // routes here pass the request on to it).
    const auto status = call.cluster->status();
    for (const auto& id : call.maps->stored_ids()) {
      if (const auto map = call.maps->find(id)) {
        auto summary = map_summary(id, service::WorldPorts(map->world));
        summary["node"] = status.node_id;
        list.push_back(std::move(summary));
        continue;
      }
      nlohmann::json entry{
          {"id", id}, {"default", false}, {"href", "/api/v1/maps/" + id}, {"node", nullptr}, {"owner", nullptr}};
      for (const auto& node : status.nodes)
        if (std::find(node.maps.begin(), node.maps.end(), id) != node.maps.end()) {
          entry["node"] = node.node;
          entry["owner"] = node.url;
        }
      list.push_back(std::move(entry));
    }
    return json_response(call.request, {{"maps", std::move(list)}});
  }
  if (call.maps)
    for (const auto& id : call.maps->ids())
      if (const auto map = call.maps->find(id)) list.push_back(map_summary(id, service::WorldPorts(map->world)));
  return json_response(call.request, {{"maps", std::move(list)}});
}

namespace {

// A map id from a building level's name: "L1" → "<prefix>-l1"; characters an id has not become '-'.
std::string level_map_id(const std::string& prefix, const std::string& level) {
  std::string id = prefix + "-";
  for (const char c : level) {
    const char lower = c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c;
    id += (lower >= 'a' && lower <= 'z') || (lower >= '0' && lower <= '9') || lower == '_' ? lower : '-';
  }
  if (!service::valid_map_id(id))
    throw bad_request("level", "level '" + level + "' makes the map id '" + id + "': " + kIdRule);
  return id;
}

// An Open-RMF building.yaml: a map per level, "<prefix>-<level>", each with its level's plan loaded. All levels are
// imported before any map is made, and the maps made are taken back when one fails: all or nothing.
Response post_building(const Call& call) {
  const auto prefix = call.target.param("prefix");
  if (!prefix || !service::valid_map_id(*prefix)) throw bad_request("prefix", "?prefix=ID: " + std::string(kIdRule));
  struct Level {
    std::string name, id;
    apriori::ImportResult imported;
  };
  std::vector<Level> levels;
  for (const auto& name : apriori::rmf_level_names(call.request.body())) {
    apriori::RmfImportOptions options;
    options.level = name;
    options.limits = call.options.plan_limits;
    options.name = name;
    levels.push_back({name, level_map_id(*prefix, name), apriori::import_rmf_building(call.request.body(), options)});
  }
  for (const auto& level : levels)
    if (level.id == service::kDefaultMapId || call.maps->find(level.id))
      throw ApiError(409, "conflict", "map '" + level.id + "' exists (level '" + level.name + "')");
  std::vector<std::string> made;
  nlohmann::json answer = nlohmann::json::array();
  try {
    for (auto& level : levels) {
      const auto map = call.maps->create(level.id);
      made.push_back(level.id);
      const auto objects = level.imported.plan.objects.size();
      map->world.load_floor_plan(std::move(level.imported.plan));
      auto entry = map_summary(level.id, service::WorldPorts(map->world));
      entry["level"] = level.name;
      entry["imported_objects"] = objects;
      answer.push_back(std::move(entry));
    }
  } catch (...) {
    for (const auto& id : made) call.maps->remove(id);
    throw;
  }
  return json_response(call.request, {{"maps", std::move(answer)}}, boost::beast::http::status::created);
}

}  // namespace

Response post_maps(const Call& call) {
  require_token(call.request, call.options);
  if (!call.maps) throw ApiError(409, "maps_disabled", "this server holds only its default map");
  if (has_content_type(call.request, "application/yaml") || has_content_type(call.request, "application/x-yaml"))
    return post_building(call);
  const auto body = parse_json_object(call.request);
  require_known_keys(body, {"id"});
  const auto id = string_field(body, "id", 64);
  if (!service::valid_map_id(id)) throw bad_request("id", kIdRule);
  const auto map = call.maps->create(id);
  return json_response(call.request, map_summary(id, service::WorldPorts(map->world)),
                       boost::beast::http::status::created);
}

Response get_map_entry(const Call& call) {
  const auto id = path_map_id(call);
  if (id == service::kDefaultMapId) return json_response(call.request, map_summary(id, call.world));
  return json_response(call.request, map_summary(id, service::WorldPorts(find_map(call, id)->world)));
}

Response delete_map(const Call& call) {
  require_token(call.request, call.options);
  const auto id = path_map_id(call);
  if (id == service::kDefaultMapId)
    throw ApiError(409, "default_map", "the default map cannot be deleted (it is the --db file)");
  if (!call.maps) throw map_not_found(id);
  const auto map = call.maps->find(id);
  call.maps->remove(id);
  // Its segment goes now (readers see it stopped), not when the last request that holds the map ends.
  if (map && call.map_exports) call.map_exports->forget(map.get());
  return json_response(call.request, {{"deleted", id}});
}

}  // namespace wm::api
