#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "server/json/codec.h"
#include "server/service/grid_store.h"
#include "server/service/robot_registry.h"
#include "server/storage/store.h"
#include "server/world/scan_observation.h"
#include "server/world/world_state.h"

// How a map comes back at start from what its store committed: the journal is the grid's source of truth, and the
// robots' last poses and tracks are journaled with their scans and reports.
namespace wm::service {

/// A journaled scan; rows stored before the journal kept scans in binary form hold the request body instead.
/// @throw json_codec::CodecError for such a body this build does not read.
inline world::ScanObservation journaled_scan(storage::JournaledScan&& record) {
  if (record.scan) return std::move(*record.scan);
  return json_codec::parse_scan(record.legacy_json, json_codec::ScanLimits{});
}

/// Calls `visit(seq, scan record)` for every journaled scan past `after`, in order, reading a page at a time.
template <typename Visit>
void for_each_journaled_scan(storage::Store& store, std::int64_t after, Visit visit) {
  constexpr std::size_t kPage = 256;
  for (;;) {
    auto page = store.scans_after(after, kPage);
    for (auto& record : page) {
      after = record.seq;
      visit(record.seq, std::move(record));
    }
    if (page.size() < kPage) return;
  }
}

/// Rebuilds the laser-only and sonar-only grids from the whole journal when it holds sonar scans (journal_has_sonar
/// of the robots' journal), then inserts every
/// journaled scan past the grid's last flush into `grid` (decided against `map`, the map as loaded), so
/// the grid and its revision reach the last journaled scan; the replayed tiles stay dirty for the next flush.
/// @throw storage::StorageError when the journal and the rebuilt grid end at different scans.
void replay_journal_into_grid(storage::Store& store, GridStore& grid, const world::WorldState& map,
                              bool journal_has_sonar);
/// Whether any robot of the journal (Store::robot_journal) sent sonar scans.
bool journal_has_sonar(const std::vector<storage::Store::RobotJournal>& robots);

/// The robots as the journal left them (Store::robot_journal with the registry's track_points): tracks, counts, and
/// the newest of the last reported pose and the last scan's pose.
void restore_robots(std::vector<storage::Store::RobotJournal> journals, RobotRegistry& robots);

}  // namespace wm::service
