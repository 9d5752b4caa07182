#pragma once

// The api's entry points for the transport: answer a request, say where it runs, decide a WebSocket upgrade.
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "common/diagnostics.h"
#include "server/api/api_options.h"
#include "server/api/http_types.h"
#include "server/api/map_cache.h"
#include "server/api/map_scope.h"
#include "server/api/response.h"
#include "server/service/cluster_member.h"
#include "server/service/world_port.h"
#include "server/shm/shared_map_export.h"

namespace wm::api {

class DriveRelay;  // server/api/drive_relay.h

/// What a node of a cluster needs to answer for maps another node serves: who serves them, and a way to pass a request
/// on to that node. A request passed on carries this node's id (X-WM-Forwarded-By) and the cluster's token
/// (X-WM-Cluster-Token); a node that is passed a request for a map it does not serve answers 503 map_moved and never
/// passes it on again.
struct ClusterRouting {
  service::ClusterMember* member = nullptr;
  std::string token;  // node to node; never empty in a cluster
  /// The other node's answer as it came; nullopt when no whole answer came (refused, reset, timed out) or
  /// `still_worth_it`, asked while it waits, said no.
  std::function<std::optional<Response>(const Request&, const std::string& base_url,
                                        const std::function<bool()>& still_worth_it)>
      forward;
};

/// What the handlers work on; built by main and passed down.
struct Services {
  ApiOptions options;
  service::WorldPorts world;
  std::shared_ptr<MapCache> map_cache = std::make_shared<MapCache>();  // the map's bytes per version
  const shm::SharedMapExport* shm = nullptr;                           // the shared-memory export, when on
  const common::Diagnostics* diagnostics = nullptr;  // what the server reported (GET /api/v1/health counts it)
  /// The maps besides the default one, served under /api/v1/maps/{map}/; nullptr: only the default map.
  service::MapRegistry* maps = nullptr;
  std::shared_ptr<MapCaches> map_caches = std::make_shared<MapCaches>();  // the map's bytes, per map of `maps`
  /// The shared-memory exports of `maps`' maps; nullptr when wmd runs with --no-shm.
  MapExports* map_exports = nullptr;
  /// This node of a cluster, whose maps other nodes serve too; nullptr: no cluster.
  ClusterRouting* cluster = nullptr;
  /// The robots' drive connections and telemetry (GET /api/v1/robots/{id}/drive); nullptr: not served.
  DriveRelay* drive = nullptr;
};

/// The answer to a request whose route is marked at_once, when it can be given on the calling (I/O) thread without
/// waiting or heavy work: the map's bytes already made, a 304. nullopt: queue it on its lane as usual. Never throws.
std::optional<SharedResponse> answer_at_once(const Request& request, Services& services);

/// The lane of the request's route (server/api/routes.cpp); a request no route answers (404, 405) is answered
/// at once.
Lane handler_lane(const Request& request);

/// Whether the request asks to upgrade a route the table names as a WebSocket (GET /api/v1/events, /foxglove).
bool is_websocket_upgrade(const Request& request);

/// Decides a WebSocket upgrade (see authorize_upgrade in server/api/access.h), then, for a route that speaks a
/// subprotocol (GET /foxglove), that the request offers it. nullopt: upgrade; otherwise the refusal to send (421, 403,
/// 401, or 400 subprotocol_required; under /api/v1/maps/{map}/, and for /foxglove?map=ID, also 400 for a bad id, 404
/// for no such map). Never throws.
std::optional<Response> authorize_events(const Request& request, Services& services);

/// For the live events of a map another node of the cluster serves: the stream's one message, {"type":"map_moved",
/// "map", "owner": its URL (empty: being taken over; ask again)}; nullopt when this node serves it or there is no
/// cluster. Never throws.
std::optional<std::string> map_events_elsewhere(const Request& request, Services& services);

/// The live events of the map an upgrade names (/api/v1/maps/{map}/events), owned with the map so that they outlive
/// its deletion while the stream runs; nullptr for the default map's (the server's own hub) or a map there is not
/// (authorize_events refused it). Never throws.
std::shared_ptr<events::EventHub> map_events_hub(const Request& request, Services& services);

/// The map a Foxglove upgrade names (/foxglove?map=ID): nullopt for none or the default map (the server's own
/// bridge), or a query that does not parse (authorize_events refused it). Never throws.
std::optional<std::string> foxglove_map(const Request& request);

/// The subprotocol the WebSocket route of this request speaks (the route table's); empty for the events stream or a
/// request that names no WebSocket route.
std::string_view websocket_subprotocol(const Request& request);

/// Answers one HTTP request: the Host check, the Origin check for requests that are not GET/HEAD, then the
/// route's handler; a path no route has is 404, a method its routes do not take is 405 with Allow. A pure
/// function of the request and the services: no sockets, never throws; every failure becomes a JSON error
/// {"error", "detail"} with its status (see http_error in server/api/error_mapping.h).
Response handle_request(const Request& request, Services& services);

}  // namespace wm::api
