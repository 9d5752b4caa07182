#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>

#include "server/service/world_port.h"
#include "server/world/world_state.h"

namespace wm::service {

/// The published map and what each published version took out of it. Readers take the current map as an immutable
/// snapshot (one pointer copy under a short lock), so they never wait for the writer and never see half an update;
/// a client that holds version v asks which ids left the map after it (GET /api/v1/map?since=v).
class SnapshotLog {
 public:
  /// `initial`: the map at start (what was removed before it is not known). `removed_ids_kept`: removals are
  /// remembered for at most this many ids (at least the newest version's, whatever its size).
  explicit SnapshotLog(world::WorldState initial, std::size_t removed_ids_kept = 100000);

  std::shared_ptr<const world::WorldState> current() const;
  /// Swaps in `state`; `removed` (the ids that left the map with it) is logged first, so that a reader of the new
  /// version finds its removals.
  void publish(world::WorldState state, MapRemovals removed = {});
  /// The ids removed by the versions in (since, up_to]; nullopt when `since` is older than the log remembers.
  std::optional<MapRemovals> removed_since(std::int64_t since, std::int64_t up_to) const;

 private:
  const std::size_t removed_ids_kept_;
  mutable std::mutex current_mutex_;
  std::shared_ptr<const world::WorldState> current_;
  mutable std::mutex removals_mutex_;
  std::int64_t removals_base_ = 0;  // every removal after this version is in removals_
  std::deque<std::pair<std::int64_t, std::shared_ptr<const MapRemovals>>> removals_;  // merged outside the lock
  std::size_t ids_kept_ = 0;
};

}  // namespace wm::service
