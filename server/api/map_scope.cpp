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

}  // namespace wm::api
