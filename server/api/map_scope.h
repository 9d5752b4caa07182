#pragma once

// Requests to one map of several: "/api/v1/maps/{map}/scans" is "/api/v1/scans" of map {map}. The route table is
// one; the path is split before it is looked up, and the handler gets the map's ports and map cache.
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "server/api/map_cache.h"
#include "server/service/map_registry.h"

namespace wm::api {

/// A path under /api/v1/maps/{map}/: the map's id (not yet validated) and the path as the default map's routes
/// name it ("/api/v1/maps/floor2/grid/tiles" → {"floor2", "/api/v1/grid/tiles"}).
struct MapScopedPath {
  std::string map;
  std::string path;
};

/// nullopt for a path that names no map's resource: "/api/v1/maps", "/api/v1/maps/{map}" itself, anything else.
std::optional<MapScopedPath> split_map_path(std::string_view path);

/// The map caches of the registry's maps, one per map instance (a map deleted and made again under the same id is
/// another map, with versions of its own). A cache goes when its map has gone. Thread-safe.
class MapCaches {
 public:
  std::shared_ptr<MapCache> of(const std::shared_ptr<service::MapInstance>& map);

 private:
  std::mutex mutex_;
  std::map<const service::MapInstance*, std::pair<std::weak_ptr<service::MapInstance>, std::shared_ptr<MapCache>>>
      caches_;
};

}  // namespace wm::api
