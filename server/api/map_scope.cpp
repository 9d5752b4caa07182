#include "server/api/map_scope.h"

#include <vector>

namespace wm::api {

std::optional<MapScopedPath> split_map_path(std::string_view path) {
  constexpr std::string_view prefix = "/api/v1/maps/";
  if (!path.starts_with(prefix)) return std::nullopt;
  const auto rest = path.substr(prefix.size());
  const auto slash = rest.find('/');
  if (slash == std::string_view::npos || slash == 0) return std::nullopt;
  return MapScopedPath{std::string(rest.substr(0, slash)), "/api/v1" + std::string(rest.substr(slash))};
}

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
