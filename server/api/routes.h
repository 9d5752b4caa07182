#pragma once

// The route table: every method and path the server answers, with its handler and lane. Dispatch, the 405 Allow
// header, the JSON index at GET /api/v1 and the WebSocket route the transport upgrades all come from it (and a
// test checks the README's API reference against it).
#include <boost/beast/http/verb.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "server/api/handlers.h"

namespace wm::api {

struct Route {
  boost::beast::http::verb method;
  /// The path; at most one "{name}" placeholder, which matches one or more characters, '/' included (edge ids
  /// are "table-1/2").
  std::string_view pattern;
  Handler handler;
  Lane lane;
  /// The query parameters it reads, as the index and the README show them ("?since=SEQ&limit=N"); empty: none.
  std::string_view query = {};
  /// A WebSocket route: an upgrade request is taken over by the transport; `handler` answers a plain GET.
  bool websocket = false;
  /// Tried first on the I/O thread (answers from bytes already made: no queue, no lower CPU priority); the request
  /// is queued on `lane` only when it answers nullopt. nullptr: always queued.
  AtOnceHandler at_once = nullptr;
  /// For a WebSocket route: the subprotocol it speaks, which an upgrade must offer (Sec-WebSocket-Protocol); empty:
  /// none (the events stream).
  std::string_view subprotocol = {};
};

/// The table, in matching order: the first route whose pattern matches the path and whose method is the
/// request's answers it.
std::span<const Route> routes();

/// Whether `pattern` matches `path`; the placeholder's text in `param` (empty for a pattern without one). A single
/// placeholder matches one or more characters, slashes included (ids like "table-1/2"); with several, each matches
/// one non-empty path segment and `param` holds them joined by '/'.
bool pattern_matches(std::string_view pattern, std::string_view path, std::string& param);

struct RouteMatch {
  const Route* route = nullptr;
  std::string param;
};
/// The route for a method and a decoded path, nullopt when none. HEAD finds the GET route.
std::optional<RouteMatch> find_route(boost::beast::http::verb method, std::string_view path);
/// The methods of the routes whose pattern matches `path`, in table order without repeats ("GET, PUT"); empty
/// when no route has this path. Under /api/v1/maps/{map}/ only a map's own routes count.
std::string allowed_methods(std::string_view path);
/// Whether a GET upgrade of this target (path and query) is one the table names as a WebSocket.
bool is_websocket_target(std::string_view target);
/// The WebSocket route of a target (path and query), nullptr when it names none; under /api/v1/maps/{map}/ only a
/// map's own (its events).
const Route* websocket_route(std::string_view target);

/// Whether a route is one map's resource, and so also answers under /api/v1/maps/{map}/ (the floor plan, scans,
/// grid, health, ...); the server's own (the index, the network, the maps, the viewer's files, the WebSockets) are
/// not.
bool is_per_map(const Route& route);

/// A path under /api/v1/maps/{map}/: the map's id (not yet validated) and the path as the default map's routes
/// name it ("/api/v1/maps/floor2/grid/tiles" → {"floor2", "/api/v1/grid/tiles"}). The route table is one; such a path
/// is split before the table is searched.
struct MapScopedPath {
  std::string map;
  std::string path;
};

/// nullopt for a path that names no map's resource: "/api/v1/maps", "/api/v1/maps/{map}" itself, anything else.
std::optional<MapScopedPath> split_map_path(std::string_view path);

/// "METHOD PATTERN" of a route, as the index and the README list it.
std::string route_name(const Route& route);

}  // namespace wm::api
