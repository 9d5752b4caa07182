#pragma once

#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "server/storage/sqlite.h"
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

  static constexpr int kSchemaVersion = 2;
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
