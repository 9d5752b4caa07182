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

#include "common/diagnostics.h"
#include "server/api/map_cache.h"
#include "server/service/map_registry.h"
#include "server/shm/shared_map_export.h"

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

/// The shared-memory exports of the registry's maps, one per map instance (segment "wm-<uuid>" of its own, found
/// through GET /api/v1/maps/{map}/shm): made when the map is first used after start (any request under it), gone when
/// the map is deleted (forget) or the server stops. An export holds its map, which it reads on its own thread.
/// Thread-safe.
class MapExports {
 public:
  /// `diagnostics` must outlive this.
  MapExports(shm::ShmOptions options, common::Diagnostics& diagnostics);
  ~MapExports();
  MapExports(const MapExports&) = delete;
  MapExports& operator=(const MapExports&) = delete;

  /// The map's export (made now if it has none), kept alive by the caller while it uses it. `session` is the map's
  /// server_instance, which the segment carries.
  std::shared_ptr<const shm::SharedMapExport> of(const std::shared_ptr<service::MapInstance>& map,
                                                 const std::string& session);
  /// The map's export goes (its segment is marked stopped and unlinked) once no request holds it.
  void forget(const service::MapInstance* map);

  struct Export;

 private:
  const shm::ShmOptions options_;
  common::Diagnostics& diagnostics_;
  std::mutex mutex_;
  std::map<const service::MapInstance*, std::shared_ptr<Export>> exports_;
};

}  // namespace wm::api
