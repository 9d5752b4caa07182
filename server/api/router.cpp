#include "server/api/router.h"

#include <boost/beast/websocket/rfc6455.hpp>

#include "server/api/access.h"
#include "server/api/api_error.h"
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
    const auto map = map_context(map_id, services);
    return match.route->handler(call_of(request, target, match, services, map));
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
  if (const auto found = route_of(request.method(), path)) return found->second.route->lane;
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
  const auto raw = target_of(request);
  if (const auto scoped = split_map_path(raw.substr(0, raw.find('?')))) {
    try {
      map_context(scoped->map, services);
    } catch (...) {
      const auto failure = http_error(std::current_exception());
      return error_response(request.version(), false, failure.status, failure.error, failure.detail);
    }
  }
  const auto protocol = websocket_subprotocol(request);
  if (!protocol.empty()) {
    // The map of a Foxglove client (/foxglove?map=ID), refused as a map route's would be.
    try {
      if (const auto map = parse_target(raw).param("map")) map_context(*map, services);
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
