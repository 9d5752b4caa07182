#pragma once

#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "server/storage/sqlite.h"
#include "fusion/grid/occupancy_grid.h"
#include "server/world/update.h"

namespace wm::storage {

struct StoreOptions {
  std::string path;  // SQLite file; created when missing
  /// synchronous=FULL makes every acknowledged request survive a power loss (one fsync per commit,
  /// ~0.3 ms here); NORMAL survives process crashes only. See SERVER.md §5.
  bool synchronous_full = true;
};

/// The world model's SQLite file: WAL, schema versioned by PRAGMA user_version with forward migrations.
/// Writes come from the single writer thread, one transaction per applied request; decision-log reads use
/// their own connection and may come from any thread.
class Store {
 public:
  /// Opens or creates the file and migrates it. @throw StorageError (also for a file newer than this build).
  explicit Store(const StoreOptions& options);

  static constexpr int kSchemaVersion = 3;
  int schema_version();

  /// The persisted world (an empty state for a new file). @throw StorageError, apriori::FloorPlanError.
  world::WorldState load(const world::WorldOptions& options);

  /// Journals the observation and writes its effects (changed rows, decisions, counters) in one transaction.
  void commit_observation(const world::UpdateResult& update, const world::Observation& observation,
                          std::string_view payload_json);
  /// Replaces the stored floor plan and objects in one transaction.
  void commit_floor_plan(const world::UpdateResult& update, const apriori::FloorPlan& plan);

  /// Decisions with seq > since_seq in order, at most `limit`; only those about `element` when given.
  std::vector<world::DecisionRecord> decisions(std::int64_t since_seq, std::size_t limit,
                                               const std::optional<std::string>& element = std::nullopt);
  /// Journals a scan (its request body) durably; returns its sequence number.
  std::int64_t append_scan(const std::string& observer, std::string_view sensor, double stamp, std::string_view payload);
  std::int64_t last_scan_seq();
  struct ScanRecord {
    std::int64_t seq = 0;
    std::string payload;
  };
  /// Journaled scans with seq > after, in order (replayed at start past the last grid flush).
  std::vector<ScanRecord> scans_after(std::int64_t after);

  /// The grid as last flushed: tiles and the last scan they include.
  struct StoredGrid {
    double resolution_m = 0;
    std::int64_t tile_size_cells = 0;
    std::int64_t through_scan_seq = 0;
    std::vector<std::pair<fusion::TileIndex, fusion::OccupancyGrid::TileData>> tiles;
  };
  /// nullopt when no grid was ever flushed.
  std::optional<StoredGrid> load_grid();
  /// Writes changed tiles and the scan sequence they include, in one transaction.
  void flush_grid(const StoredGrid& changed);

  /// Decisions about a CAD object (about the object or any of its edges), in order, at most `limit`.
  std::vector<world::DecisionRecord> object_decisions(const std::string& object_id, std::size_t limit);

  /// The `count` newest decisions about posted segments (not prunes), oldest first.
  std::vector<world::DecisionRecord> latest_decisions(std::size_t count);

 private:
  void migrate();
  void write_counters(const world::WorldState& state);
  void write_objects(const world::UpdateResult& update);
  void insert_observation(std::int64_t seq, std::string_view kind, const std::string& observer, double stamp,
                          std::string_view payload);

  StoreOptions options_;
  Connection writer_;
  std::mutex reader_mutex_;
  Connection reader_;
};

}  // namespace wm::storage
