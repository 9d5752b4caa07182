#include "server/api/routes.h"

#include <algorithm>
#include <array>

namespace wm::api {
namespace {

using boost::beast::http::verb;

// Lanes: health and the index answer on the I/O thread even when every handler is busy; reads (and queries and
// dry runs, which wait for the Prolog reader, not the writer) on the niced read lane; writes on their own lane.
// Order matters where patterns overlap: ".../{id}/history" before ".../{id}".
constexpr std::array kRoutes{
    Route{verb::get, "/", get_root, Lane::read},
    Route{verb::get, "/api/v1", get_index, Lane::immediate},
    Route{verb::get, "/api/v1/health", get_health, Lane::immediate},
    Route{verb::get, "/api/v1/network", get_network, Lane::read},
    Route{verb::put, "/api/v1/network/subtasks/{name}", put_network_subtask, Lane::write},
    Route{verb::put, "/api/v1/network/components/{name}/params", put_network_params, Lane::write},
    Route{verb::get, "/api/v1/floorplan", get_floor_plan, Lane::read},
    Route{verb::put, "/api/v1/floorplan", put_floor_plan, Lane::write, "?units=U&level=L&name=N"},
    Route{verb::post, "/api/v1/floorplan/place", post_floor_plan_place, Lane::write},
    Route{verb::post, "/api/v1/floorplan/pairs", post_floor_plan_pairs, Lane::write},
    // On the read lane: a search takes up to its time budget and must not hold back the writes; one at a time.
    Route{verb::post, "/api/v1/floorplan/align", post_floor_plan_align, Lane::read},
    Route{verb::post, "/api/v1/floorplan/undo", post_floor_plan_undo, Lane::write},
    Route{verb::post, "/api/v1/floorplan/redecide", post_floor_plan_redecide, Lane::write},
    Route{verb::put, "/api/v1/floorplan/georeference", put_georeference, Lane::write},
    Route{verb::delete_, "/api/v1/floorplan/georeference", delete_georeference, Lane::write},
    Route{verb::get, "/api/v1/map", get_map, Lane::read, "?format=json|dxf|geojson&bbox=x0,y0,x1,y1&since=V", false,
          get_map_at_once},
    Route{verb::get, "/api/v1/map/quality", get_map_quality, Lane::read},
    Route{verb::get, "/api/v1/report/as-built", get_as_built_report, Lane::read},
    Route{verb::get, "/api/v1/changes", get_changes, Lane::read},
    Route{verb::post, "/api/v1/changes/undo", post_changes_undo, Lane::write},
    Route{verb::post, "/api/v1/changes/{id}/accept", post_change_accept, Lane::write},
    Route{verb::post, "/api/v1/changes/{id}/reject", post_change_reject, Lane::write},
    Route{verb::get, "/api/v1/objects", get_objects, Lane::read},
    Route{verb::get, "/api/v1/objects/{id}/history", get_object_history, Lane::read},
    Route{verb::get, "/api/v1/objects/{id}", get_object, Lane::read},
    Route{verb::get, "/api/v1/elements", get_elements, Lane::read},
    Route{verb::get, "/api/v1/elements/{id}/history", get_element_history, Lane::read},
    Route{verb::get, "/api/v1/elements/{id}", get_element, Lane::read},
    Route{verb::post, "/api/v1/primitives", post_primitives, Lane::write},
    Route{verb::get, "/api/v1/decisions", get_decisions, Lane::read, "?since=SEQ&limit=N&element=ID"},
    Route{verb::get, "/api/v1/rules", get_rules, Lane::read},
    Route{verb::post, "/api/v1/rules/reload", post_rules_reload, Lane::write},
    Route{verb::post, "/api/v1/rules/dry-run", post_rules_dry_run, Lane::read},
    Route{verb::post, "/api/v1/query", post_query, Lane::read},
    Route{verb::post, "/api/v1/scans", post_scan, Lane::write},
    Route{verb::get, "/api/v1/grid", get_grid, Lane::read, "?layer=L&bbox=x0,y0,x1,y1&format=json|pgm"},
    Route{verb::post, "/api/v1/grid/extract", post_grid_extract, Lane::write},
    Route{verb::get, "/api/v1/grid/map.yaml", get_grid_map_yaml, Lane::read, "?bbox=x0,y0,x1,y1"},
    Route{verb::get, "/api/v1/grid/map.pgm", get_grid_map_pgm, Lane::read, "?bbox=x0,y0,x1,y1"},
    Route{verb::get, "/api/v1/grid/tiles", get_grid_tiles, Lane::read},
    Route{verb::get, "/api/v1/grid/tiles/{layer}/{tx}/{ty}", get_grid_tile, Lane::read},
    Route{verb::get, "/api/v1/shm", get_shm, Lane::read},
    Route{verb::get, "/api/v1/robots", get_robots, Lane::read},
    Route{verb::put, "/api/v1/robots/{id}/pose", put_robot_pose, Lane::write},
    // Driving a robot from a browser through wmd (drive_relay.h): the robot side and one driver.
    Route{verb::get, "/api/v1/robots/{id}/drive", get_websocket_without_upgrade, Lane::immediate,
          "?role=driver|robot&token=TOKEN", true},
    Route{verb::get, "/api/v1/robots/{id}", get_robot, Lane::read},
    Route{verb::get, "/api/v1/maps", get_maps, Lane::read},
    Route{verb::post, "/api/v1/maps", post_maps, Lane::write},
    // A map's own resources, "/api/v1/maps/{map}/...", are split off before the table is searched (map_scope.h).
    Route{verb::get, "/api/v1/maps/{map}", get_map_entry, Lane::read},
    Route{verb::delete_, "/api/v1/maps/{map}", delete_map, Lane::write},
    Route{verb::get, "/api/v1/cluster", get_cluster, Lane::read},
    Route{verb::get, "/api/v1/events", get_websocket_without_upgrade, Lane::immediate, "?token=TOKEN", true},
    // Foxglove's protocol, outside /api/v1: it is versioned by its subprotocol, not by this API's version.
    Route{verb::get, "/foxglove", get_websocket_without_upgrade, Lane::immediate, "?token=TOKEN", true, nullptr,
          "foxglove.websocket.v1"},
    Route{verb::get, "/web/{path}", get_static, Lane::read},
};

std::string method_name(verb method) {
  const auto name = boost::beast::http::to_string(method);
  return std::string(name.data(), name.size());
}

}  // namespace

std::span<const Route> routes() { return kRoutes; }

bool pattern_matches(std::string_view pattern, std::string_view path, std::string& param) {
  const auto open = pattern.find('{');
  if (open == std::string_view::npos) {
    param.clear();
    return pattern == path;
  }
  const auto close = pattern.find('}', open);
  if (pattern.find('{', close) != std::string_view::npos) {
    // Several placeholders: one path segment each, given to the handler joined by '/'.
    param.clear();
    while (!pattern.empty() || !path.empty()) {
      const auto pattern_end = pattern.find('/', 1), path_end = path.find('/', 1);
      const auto p = pattern.substr(0, pattern_end), q = path.substr(0, path_end);
      if (p.size() > 2 && p[1] == '{') {
        if (q.size() < 2 || q[0] != '/') return false;
        param += (param.empty() ? "" : "/") + std::string(q.substr(1));
      } else if (p != q) {
        return false;
      }
      pattern = pattern_end == std::string_view::npos ? std::string_view{} : pattern.substr(pattern_end);
      path = path_end == std::string_view::npos ? std::string_view{} : path.substr(path_end);
    }
    return true;
  }
  const auto prefix = pattern.substr(0, open);
  const auto suffix = pattern.substr(close + 1);
  if (path.size() <= prefix.size() + suffix.size() || !path.starts_with(prefix) || !path.ends_with(suffix))
    return false;
  param.assign(path.substr(prefix.size(), path.size() - prefix.size() - suffix.size()));
  return true;
}

std::optional<RouteMatch> find_route(verb method, std::string_view path) {
  RouteMatch match;
  const auto wanted = method == verb::head ? verb::get : method;  // HEAD is a GET without the body
  for (const auto& route : kRoutes) {
    if (route.method == wanted && pattern_matches(route.pattern, path, match.param)) {
      match.route = &route;
      return match;
    }
  }
  return std::nullopt;
}

std::string allowed_methods(std::string_view path) {
  const auto scoped = split_map_path(path);
  if (scoped) path = scoped->path;
  std::vector<verb> methods;
  std::string ignored;
  for (const auto& route : kRoutes)
    if (pattern_matches(route.pattern, path, ignored) && (!scoped || is_per_map(route)) &&
        std::find(methods.begin(), methods.end(), route.method) == methods.end())
      methods.push_back(route.method);
  std::string allow;
  for (const auto method : methods) {
    if (!allow.empty()) allow += ", ";
    allow += method_name(method);
    if (method == verb::get) allow += ", HEAD";
  }
  return allow;
}

bool is_websocket_target(std::string_view target) { return websocket_route(target) != nullptr; }

const Route* websocket_route(std::string_view target) {
  const auto raw_path = target.substr(0, target.find('?'));
  const auto scoped = split_map_path(raw_path);
  const std::string_view path = scoped ? std::string_view(scoped->path) : raw_path;
  std::string ignored;
  const auto it = std::find_if(kRoutes.begin(), kRoutes.end(), [&](const Route& route) {
    return route.websocket && route.method == verb::get && pattern_matches(route.pattern, path, ignored) &&
           (!scoped || is_per_map(route));
  });
  return it == kRoutes.end() ? nullptr : &*it;
}

std::optional<MapScopedPath> split_map_path(std::string_view path) {
  constexpr std::string_view prefix = "/api/v1/maps/";
  if (!path.starts_with(prefix)) return std::nullopt;
  const auto rest = path.substr(prefix.size());
  const auto slash = rest.find('/');
  if (slash == std::string_view::npos || slash == 0) return std::nullopt;
  std::string route_path("/api/v1");
  route_path.append(rest.substr(slash));  // appended, not "literal" + string: GCC 12 warns falsely (-Wrestrict) there
  return MapScopedPath{std::string(rest.substr(0, slash)), std::move(route_path)};
}

bool is_per_map(const Route& route) {
  constexpr std::array<std::string_view, 11> server_wide{"/",
                                                         "/api/v1",
                                                         "/api/v1/network",
                                                         "/api/v1/network/subtasks/{name}",
                                                         "/api/v1/network/components/{name}/params",
                                                         "/api/v1/maps",
                                                         "/api/v1/maps/{map}",
                                                         "/api/v1/cluster",
                                                         "/foxglove",
                                                         "/api/v1/robots/{id}/drive",
                                                         "/web/{path}"};
  return std::find(server_wide.begin(), server_wide.end(), route.pattern) == server_wide.end();
}

std::string route_name(const Route& route) { return method_name(route.method) + " " + std::string(route.pattern); }

}  // namespace wm::api
