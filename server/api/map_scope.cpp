#include "server/api/map_scope.h"

#include <vector>

namespace wm::api {

std::shared_ptr<MapCache> MapCaches::of(const std::shared_ptr<service::MapInstance>& map) {
  std::vector<std::shared_ptr<MapCache>> gone;  // released after the lock: a cache waits for its background build
  std::lock_guard lock(mutex_);
  for (auto it = caches_.begin(); it != caches_.end();) {
    if (it->second.first.expired()) {
      gone.push_back(std::move(it->second.second));
      it = caches_.erase(it);
    } else {
      ++it;
    }
  }
  auto& entry = caches_[map.get()];
  if (!entry.second) entry = {map, std::make_shared<MapCache>()};
  return entry.second;
}

// A map's export and the map it reads: the export goes first (its thread stops), then the map is let go.
struct MapExports::Export {
  Export(std::shared_ptr<service::MapInstance> instance, const shm::ShmOptions& options, const std::string& session,
         common::Diagnostics& diagnostics)
      : map(std::move(instance)), exporter(map->world, options, session, diagnostics, &map->events) {}

  std::shared_ptr<service::MapInstance> map;
  shm::SharedMapExport exporter;
};

MapExports::MapExports(shm::ShmOptions options, common::Diagnostics& diagnostics)
    : options_(options), diagnostics_(diagnostics) {}

MapExports::~MapExports() = default;

std::shared_ptr<const shm::SharedMapExport> MapExports::of(const std::shared_ptr<service::MapInstance>& map,
                                                           const std::string& session) {
  std::lock_guard lock(mutex_);
  auto& entry = exports_[map.get()];
  if (!entry) entry = std::make_shared<Export>(map, options_, session, diagnostics_);
  return {entry, &entry->exporter};
}

void MapExports::forget(const service::MapInstance* map) {
  std::shared_ptr<Export> gone;  // released after the lock: its thread is joined
  {
    std::lock_guard lock(mutex_);
    const auto it = exports_.find(map);
    if (it == exports_.end()) return;
    gone = std::move(it->second);
    exports_.erase(it);
  }
}

}  // namespace wm::api
