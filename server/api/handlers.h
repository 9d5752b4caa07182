#pragma once

// The request handlers, one file per resource under server/api/handlers/. Each is a pure function of the call
// (request, its decoded target, the path parameter, the options and the service port) to a response: no sockets,
// no store, no Prolog. A refusal is thrown (ApiError, or a module's own error) and becomes JSON in http_error().
// Which handler answers which method and path is said once, in the route table (server/api/routes.cpp).
#include <memory>
#include <optional>
#include <string>

#include "common/diagnostics.h"
#include "server/api/api_options.h"
#include "server/api/http_types.h"
#include "server/api/map_cache.h"
#include "server/api/request.h"
#include "server/service/cluster_member.h"
#include "server/service/map_registry.h"
#include "server/service/world_port.h"
#include "server/shm/shared_map_export.h"

namespace wm::api {

class MapExports;  // server/api/map_scope.h
class DriveRelay;  // server/api/drive_relay.h

/// One request as a handler sees it.
struct Call {
  const Request& request;
  const Target& target;      // the percent-decoded path and query parameters
  const std::string& param;  // what the route pattern's {placeholder} matched; empty when it has none
  const ApiOptions& options;
  const service::WorldPorts& world;  // the service's ports: map, ingest, plan, rules, grid, robots
  MapCache& map_cache;
  const shm::SharedMapExport* shm = nullptr;         // the map's export; nullptr when wmd runs with --no-shm
  const common::Diagnostics* diagnostics = nullptr;  // nullptr: the health answer has no "diagnostics"
  /// The map the request is about: kDefaultMapId for today's routes, {map} under /api/v1/maps/{map}/.
  std::string_view map_id = service::kDefaultMapId;
  bool map_scoped = false;               // the path named the map (/api/v1/maps/{map}/...), rather than today's routes
  service::MapRegistry* maps = nullptr;  // the server's other maps; nullptr: it has only the default map
  MapExports* map_exports = nullptr;     // their shared-memory exports; nullptr: none (--no-shm)
  service::ClusterMember* cluster = nullptr;  // this node of a cluster; nullptr: no cluster
  DriveRelay* drive = nullptr;                // robots' drive connections and telemetry; nullptr: none
};

using Handler = Response (*)(const Call&);
/// A route's answer on an I/O thread, from what is ready only (no waiting, no heavy work): nullopt when it is not,
/// and the request then goes to its lane's handler as usual. A body of bytes kept elsewhere goes to `shared_body`,
/// not into the response.
using AtOnceHandler = std::optional<Response> (*)(const Call&, std::shared_ptr<const std::string>& shared_body);

// handlers/health.cpp, index.cpp
Response get_health(const Call& call);
Response get_network(const Call& call);
Response put_network_subtask(const Call& call);
Response put_network_params(const Call& call);
Response get_index(const Call& call);  // GET /api/v1: the route table as JSON
Response get_root(const Call& call);   // GET /: the viewer's index.html when served, else the index
// handlers/cluster.cpp
Response get_cluster(const Call& call);  // GET /api/v1/cluster: nodes, leases, epochs
// handlers/floorplan.cpp
Response get_floor_plan(const Call& call);
Response put_floor_plan(const Call& call);
Response post_floor_plan_place(const Call& call);     // POST /api/v1/floorplan/place: an explicit placement
Response post_floor_plan_pairs(const Call& call);     // POST /api/v1/floorplan/pairs: from plan ↔ world point pairs
Response post_floor_plan_align(const Call& call);     // POST /api/v1/floorplan/align: searched against the grid
Response post_floor_plan_undo(const Call& call);      // POST /api/v1/floorplan/undo: the placement before
Response post_floor_plan_redecide(const Call& call);  // POST /api/v1/floorplan/redecide
Response put_georeference(const Call& call);          // PUT /api/v1/floorplan/georeference
Response delete_georeference(const Call& call);
// handlers/map.cpp
Response get_map(const Call& call);
std::optional<Response> get_map_at_once(const Call& call, std::shared_ptr<const std::string>& shared_body);
Response get_map_quality(const Call& call);  // GET /api/v1/map/quality
// handlers/objects.cpp: CAD objects, observed elements and their decision histories
Response get_objects(const Call& call);
Response get_object(const Call& call);
Response get_object_history(const Call& call);
Response get_elements(const Call& call);
Response get_element(const Call& call);
Response get_element_history(const Call& call);
// handlers/primitives.cpp, scans.cpp
Response post_primitives(const Call& call);
Response post_scan(const Call& call);
// handlers/grid.cpp
Response get_grid(const Call& call);
Response get_grid_map_yaml(const Call& call);
Response get_grid_map_pgm(const Call& call);
Response get_grid_tiles(const Call& call);  // GET /api/v1/grid/tiles: the tiles and their revisions
Response get_grid_tile(const Call& call);   // GET /api/v1/grid/tiles/{layer}/{tx}/{ty}: one tile, float32
// handlers/robots.cpp
Response get_robots(const Call& call);
Response get_robot(const Call& call);
Response put_robot_pose(const Call& call);  // PUT /api/v1/robots/{id}/pose: a pose reported without a scan
// handlers/shm.cpp
Response get_shm(const Call& call);  // GET /api/v1/shm: the shared-memory segment's name and layout
Response post_grid_extract(const Call& call);
// handlers/rules.cpp, query.cpp, decisions.cpp, reports.cpp
Response get_rules(const Call& call);
Response post_rules_reload(const Call& call);
Response post_rules_dry_run(const Call& call);
Response post_query(const Call& call);
Response get_decisions(const Call& call);
Response get_as_built_report(const Call& call);
Response get_changes(const Call& call);         // GET /api/v1/changes
Response post_change_accept(const Call& call);  // POST /api/v1/changes/{id}/accept
Response post_change_reject(const Call& call);  // POST /api/v1/changes/{id}/reject
Response post_changes_undo(const Call& call);   // POST /api/v1/changes/undo
// handlers/maps.cpp: the maps a server holds
Response get_maps(const Call& call);       // GET /api/v1/maps
Response post_maps(const Call& call);      // POST /api/v1/maps: a new, empty map
Response get_map_entry(const Call& call);  // GET /api/v1/maps/{map}
Response delete_map(const Call& call);     // DELETE /api/v1/maps/{map}: the map and its file
// handlers/static_files.cpp
Response get_static(const Call& call);
// handlers/events.cpp: a plain GET of a WebSocket route (the events, Foxglove), which only answers upgrades
Response get_websocket_without_upgrade(const Call& call);

}  // namespace wm::api
