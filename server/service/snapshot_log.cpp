#include "server/service/snapshot_log.h"

#include <vector>

namespace wm::service {

SnapshotLog::SnapshotLog(world::WorldState initial, std::size_t removed_ids_kept)
    : removed_ids_kept_(removed_ids_kept), current_(std::make_shared<const world::WorldState>(std::move(initial))) {
  removals_base_ = current_->version;
}

std::shared_ptr<const world::WorldState> SnapshotLog::current() const {
  std::lock_guard lock(current_mutex_);
  return current_;
}

void SnapshotLog::publish(world::WorldState state, MapRemovals removed) {
  auto next = std::make_shared<const world::WorldState>(std::move(state));
  if (!removed.elements.empty() || !removed.objects.empty()) {
    auto entry = std::make_shared<const MapRemovals>(std::move(removed));
    std::lock_guard lock(removals_mutex_);
    ids_kept_ += entry->elements.size() + entry->objects.size();
    removals_.emplace_back(next->version, std::move(entry));
    while (ids_kept_ > removed_ids_kept_ && removals_.size() > 1) {
      removals_base_ = removals_.front().first;
      ids_kept_ -= removals_.front().second->elements.size() + removals_.front().second->objects.size();
      removals_.pop_front();
    }
  }
  std::lock_guard lock(current_mutex_);
  current_ = std::move(next);
}

std::optional<MapRemovals> SnapshotLog::removed_since(std::int64_t since, std::int64_t up_to) const {
  // The entries are taken under the lock and merged outside it: the writer publishing next never waits for that.
  std::vector<std::shared_ptr<const MapRemovals>> entries;
  {
    std::lock_guard lock(removals_mutex_);
    if (since < removals_base_) return std::nullopt;
    for (const auto& [version, removed] : removals_) {
      if (version <= since) continue;
      if (version > up_to) break;
      entries.push_back(removed);
    }
  }
  MapRemovals result;
  for (const auto& removed : entries) {
    result.elements.insert(removed->elements.begin(), removed->elements.end());
    result.objects.insert(removed->objects.begin(), removed->objects.end());
  }
  return result;
}

}  // namespace wm::service
