#include "server/api/router.h"

#include <boost/beast/websocket/rfc6455.hpp>

#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/drive_relay.h"
#include "server/api/error_mapping.h"
#include "server/api/request.h"
#include "server/api/routes.h"
#include "server/service/map_registry.h"

namespace wm::api {
namespace {

namespace http = boost::beast::http;

std::string_view target_of(const Request& request) {
  const auto target = request.target();
  return {target.data(), target.size()};
}

// The checks every request passes before its route's handler: Host, and Origin for anything but GET/HEAD.
void require_allowed_sender(const Request& request, const Services& services) {
  require_allowed_host(request, services.options);
  // Browsers send simple cross-site POSTs (a form, text/plain) without asking first: whatever changes state
  // must come from our own pages or an allowed origin.
  if (request.method() != http::verb::get && request.method() != http::verb::head)
    require_allowed_origin(request, services.options);
}

// The map a request is about and what its handler works on: the default map's ports and cache, or one map of the
// registry, held while the request runs (a map deleted meanwhile stays whole until it ends).
struct MapContext {
  std::string id = std::string(service::kDefaultMapId);
  std::shared_ptr<service::MapInstance> instance;  // null for the default map
  std::optional<service::WorldPorts> ports;        // the instance's
  std::shared_ptr<MapCache> cache;
  std::shared_ptr<const shm::SharedMapExport> shm;  // the instance's, held while the call runs
  bool scoped = false;                              // named in the path
};

MapContext map_context(const std::optional<std::string>& path_id, Services& services) {
  MapContext context;
  context.scoped = path_id.has_value();
  const auto id = path_id.value_or(std::string(service::kDefaultMapId));
  if (id == service::kDefaultMapId) {
    context.cache = services.map_cache;
    return context;
  }
  if (!service::valid_map_id(id)) throw bad_request("map", std::string(service::kMapIdRule));
  context.instance = services.maps ? services.maps->find(id) : nullptr;
  if (!context.instance) throw map_not_found(id);
  context.id = id;
  context.ports.emplace(context.instance->world);
  context.cache = services.map_caches->of(context.instance);
  if (services.map_exports) context.shm = services.map_exports->of(context.instance, context.cache->instance());
  return context;
}

constexpr const char* kForwardedBy = "X-WM-Forwarded-By";
constexpr const char* kClusterToken = "X-WM-Cluster-Token";
constexpr const char* kServedBy = "X-WM-Node";
constexpr const char* kEpoch = "X-WM-Epoch";

// Compared in a time that does not depend on where the texts differ.
bool same_secret(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  unsigned char differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differ |= static_cast<unsigned char>(a[i] ^ b[i]);
  return differ == 0;
}

// The map a request names that this node of a cluster may have to pass on: a map's own route, or the map itself
// (GET/DELETE /api/v1/maps/{map}). nullopt: the default map, a server-wide route, or no cluster.
std::optional<std::string> clustered_map(const std::optional<std::string>& path_id, const RouteMatch& match,
                                         const Services& services) {
  if (!services.cluster) return std::nullopt;
  auto id = path_id;
  if (!id && match.route->pattern == "/api/v1/maps/{map}") id = match.param;
  if (!id || *id == service::kDefaultMapId || !service::valid_map_id(*id)) return std::nullopt;
  return id;
}

// The answer for a map of the cluster that another node serves: that node's, the request passed on as it came. A
// request another node passed on is never passed on again (503 map_moved: the client asks again). nullopt: this node
// serves the map, or no node has it (404 as without a cluster).
std::optional<Response> answer_elsewhere(const Request& request, const std::string& id, Services& services) {
  if (services.maps && services.maps->find(id)) return std::nullopt;
  auto& cluster = *services.cluster;
  const auto forwarded_by = request.find(kForwardedBy);
  if (forwarded_by != request.end()) {
    const auto token = request.find(kClusterToken);
    if (token == request.end() ||
        !same_secret(std::string_view(token->value().data(), token->value().size()), cluster.token))
      throw ApiError(403, "forbidden", "a request passed on by another node needs the cluster's token");
    throw ApiError(503, "map_moved", "map '" + id + "' is not served by this node (any more): ask again");
  }
  std::optional<service::MapOwner> owner;
  try {
    owner = cluster.member->owner_of(id);
  } catch (const std::exception& e) {
    throw ApiError(503, "store_unavailable", std::string("the cluster's database does not answer: ") + e.what());
  }
  if (!owner) {
    if (!cluster.member->has_map(id)) return std::nullopt;
    throw ApiError(503, "map_unavailable",
                   "map '" + id + "' waits for a node to take it over (its node stopped): ask again in a second");
  }
  if (owner->node == cluster.member->options().node_id || owner->url.empty())
    throw ApiError(503, "map_unavailable", "map '" + id + "' is being opened: ask again in a second");
  Request passed = request;
  passed.set(kForwardedBy, cluster.member->options().node_id);
  passed.set(kClusterToken, cluster.token);
  // Waited for while that node still serves the map: one paused past its lease is given up on at once.
  const auto still_owner = [&cluster, &id, node = owner->node] {
    try {
      const auto now = cluster.member->owner_of(id);
      return now && now->node == node;
    } catch (const std::exception&) {
      return true;  // the database does not say: the request's own deadline decides
    }
  };
  auto answer = cluster.forward(passed, owner->url, still_owner);
  if (!answer)
    throw ApiError(503, "map_unavailable",
                   "the node serving map '" + id + "' (" + owner->url + ") did not answer: ask again in a second");
  answer->keep_alive(request.keep_alive());
  return answer;
}

Call call_of(const Request& request, const Target& target, const RouteMatch& match, const Services& services,
             const MapContext& map) {
  Call call{request,
            target,
            match.param,
            services.options,
            map.ports ? *map.ports : services.world,
            *map.cache,
            map.instance ? map.shm.get() : services.shm,
            services.diagnostics};
  call.map_id = map.id;
  call.map_scoped = map.scoped;
  call.maps = services.maps;
  call.map_exports = services.map_exports;
  call.cluster = services.cluster ? services.cluster->member : nullptr;
  call.drive = services.drive;
  return call;
}

// The route of a method and a path, the map path split off first: {map's id, route}; nullopt when no route answers
// it (or a server-wide route is asked for under a map).
std::optional<std::pair<std::optional<std::string>, RouteMatch>> route_of(http::verb method, std::string_view path) {
  if (auto scoped = split_map_path(path)) {
    auto match = find_route(method, scoped->path);
    if (!match || !is_per_map(*match->route)) return std::nullopt;
    return std::pair{std::optional<std::string>(std::move(scoped->map)), std::move(*match)};
  }
  auto match = find_route(method, path);
  if (!match) return std::nullopt;
  return std::pair{std::optional<std::string>(), std::move(*match)};
}

Response dispatch(const Request& request, Services& services) {
  require_allowed_sender(request, services);
  const Target target = parse_target(target_of(request));
  if (const auto found = route_of(request.method(), target.path)) {
    const auto& [map_id, match] = *found;
    if (const auto clustered = clustered_map(map_id, match, services))
      if (auto answer = answer_elsewhere(request, *clustered, services)) return std::move(*answer);
    const auto map = map_context(map_id, services);
    auto response = match.route->handler(call_of(request, target, match, services, map));
    if (services.cluster && map.instance) {
      // Which node answered for a map of the cluster, under which lease: what a client (or a test) checks a takeover
      // by.
      response.set(kServedBy, services.cluster->member->options().node_id);
      if (const auto& fence = map.instance->store.fence()) response.set(kEpoch, std::to_string(fence->epoch));
    }
    return response;
  }
  const auto allow = allowed_methods(target.path);
  if (allow.empty()) throw ApiError(404, "not_found", "no resource at '" + target.path + "'");
  auto response =
      error_response(request.version(), request.keep_alive(), 405, "method_not_allowed", "allowed: " + allow);
  response.set(http::field::allow, allow);
  return response;
}

}  // namespace

Lane handler_lane(const Request& request) {
  const auto target = target_of(request);
  const auto path = target.substr(0, target.find('?'));
  if (const auto found = route_of(request.method(), path)) {
    // A map's own route never runs on the I/O thread: in a cluster its answer may come from another node.
    if (found->first && found->second.route->lane == Lane::immediate) return Lane::read;
    return found->second.route->lane;
  }
  // A path that decoding changes ("%2F", "+") may still name a route once decoded: run it on a handler lane as
  // any read or write. Otherwise no route answers it, and its 404 or 405 is answered at once.
  if (path.find_first_of("%+") != std::string_view::npos)
    return request.method() == http::verb::get || request.method() == http::verb::head ? Lane::read : Lane::write;
  return Lane::immediate;
}

bool is_websocket_upgrade(const Request& request) {
  return boost::beast::websocket::is_upgrade(request) && is_websocket_target(target_of(request));
}

std::optional<Response> authorize_events(const Request& request, Services& services) {
  if (auto refusal = authorize_upgrade(request, services.options)) return refusal;
  if (auto refusal = authorize_drive(request)) return refusal;
  const auto raw = target_of(request);
  if (const auto scoped = split_map_path(raw.substr(0, raw.find('?')))) {
    if (map_events_elsewhere(request, services)) return std::nullopt;  // told where the map is, then closed
    try {
      map_context(scoped->map, services);
    } catch (...) {
      const auto failure = http_error(std::current_exception());
      return error_response(request.version(), false, failure.status, failure.error, failure.detail);
    }
  }
  const auto protocol = websocket_subprotocol(request);
  if (!protocol.empty()) {
    // The map of a Foxglove client (/foxglove?map=ID), refused as a map route's would be; in a cluster, one another
    // node serves is named with that node (a Foxglove connection is not passed on).
    try {
      if (const auto map = parse_target(raw).param("map")) {
        if (services.cluster && service::valid_map_id(*map) && *map != service::kDefaultMapId && services.maps &&
            !services.maps->find(*map))
          if (const auto owner = services.cluster->member->owner_of(*map))
            return error_response(request.version(), false, 503, "map_moved",
                                  "map '" + *map + "' is served by node " + owner->node + ": connect to " + owner->url +
                                      "/foxglove?map=" + *map);
        map_context(*map, services);
      }
    } catch (...) {
      const auto failure = http_error(std::current_exception());
      return error_response(request.version(), false, failure.status, failure.error, failure.detail);
    }
  }
  if (protocol.empty() || offers_subprotocol(request, protocol)) return std::nullopt;
  const auto target = target_of(request);
  return error_response(request.version(), false, 400, "subprotocol_required",
                        "GET " + std::string(target.substr(0, target.find('?'))) +
                            " speaks the WebSocket subprotocol " + std::string(protocol) +
                            ": offer it in 'Sec-WebSocket-Protocol: " + std::string(protocol) +
                            "' (Foxglove Studio does)");
}

std::optional<std::string> map_events_elsewhere(const Request& request, Services& services) {
  if (!services.cluster || !services.maps) return std::nullopt;
  const auto raw = target_of(request);
  const auto scoped = split_map_path(raw.substr(0, raw.find('?')));
  if (!scoped || !service::valid_map_id(scoped->map) || scoped->map == service::kDefaultMapId ||
      services.maps->find(scoped->map))
    return std::nullopt;
  try {
    const auto owner = services.cluster->member->owner_of(scoped->map);
    if (!owner && !services.cluster->member->has_map(scoped->map)) return std::nullopt;  // 404 as without a cluster
    const bool here = owner && owner->node == services.cluster->member->options().node_id;
    return nlohmann::json{{"type", "map_moved"}, {"map", scoped->map}, {"owner", owner && !here ? owner->url : ""}}
        .dump();
  } catch (...) {
    return std::nullopt;
  }
}

std::shared_ptr<events::EventHub> map_events_hub(const Request& request, Services& services) {
  const auto raw = target_of(request);
  const auto scoped = split_map_path(raw.substr(0, raw.find('?')));
  if (!scoped || !services.maps || !service::valid_map_id(scoped->map)) return nullptr;
  auto map = services.maps->find(scoped->map);
  if (!map) return nullptr;
  return std::shared_ptr<events::EventHub>(map, &map->events);
}

std::optional<std::string> foxglove_map(const Request& request) {
  try {
    auto map = parse_target(target_of(request)).param("map");
    if (!map || *map == service::kDefaultMapId) return std::nullopt;
    return map;
  } catch (...) {
    return std::nullopt;
  }
}

std::string_view websocket_subprotocol(const Request& request) {
  const auto* route = websocket_route(target_of(request));
  return route ? route->subprotocol : std::string_view{};
}

std::optional<SharedResponse> answer_at_once(const Request& request, Services& services) {
  const auto raw = target_of(request);
  const auto found = route_of(request.method(), raw.substr(0, raw.find('?')));
  if (!found || !found->second.route->at_once) return std::nullopt;  // the common case: one lookup, nothing else
  const auto& [map_id, match] = *found;
  // A map of the cluster another node serves is passed on from a handler lane.
  if (const auto clustered = clustered_map(map_id, match, services))
    if (!services.maps || !services.maps->find(*clustered)) return std::nullopt;
  // A path with escapes may decode to another route (or another placeholder's text): that one goes to its lane,
  // where the decoded path is looked up. Without them the decoded path is the raw one, and `match` stands.
  if (raw.substr(0, raw.find('?')).find_first_of("%+") != std::string_view::npos) return std::nullopt;
  std::shared_ptr<const std::string> shared;
  Response response;
  try {
    require_allowed_sender(request, services);
    const Target target = parse_target(raw);
    const auto map = map_context(map_id, services);
    auto answer = match.route->at_once(call_of(request, target, match, services, map), shared);
    if (!answer) return std::nullopt;
    response = for_request_method(request, std::move(*answer));
  } catch (...) {  // a refused Host, a bad parameter: answered at once, as on a handler thread
    shared.reset();
    const auto failure = http_error(std::current_exception());
    response = for_request_method(request, error_response(request.version(), request.keep_alive(), failure.status,
                                                          failure.error, failure.detail));
  }
  // The headers as made; the body shared (a HEAD has its Content-Length and no body) or, when the handler made one
  // of its own, moved in.
  SharedResponse answer{std::move(response.base())};
  if (shared) {
    if (request.method() != http::verb::head) answer.body() = std::move(shared);
  } else if (!response.body().empty()) {
    answer.body() = std::make_shared<const std::string>(std::move(response.body()));
  }
  return answer;
}

Response handle_request(const Request& request, Services& services) {
  try {
    return for_request_method(request, dispatch(request, services));
  } catch (...) {
    const auto failure = http_error(std::current_exception());
    return for_request_method(request, error_response(request.version(), request.keep_alive(), failure.status,
                                                      failure.error, failure.detail));
  }
}

}  // namespace wm::api
