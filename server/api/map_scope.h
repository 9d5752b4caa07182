#pragma once

// The map caches of one server's maps: a request under /api/v1/maps/{map}/ (split_map_path, routes.h) gets its map's
// ports and its map cache.
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
