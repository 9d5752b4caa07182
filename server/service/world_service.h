#pragma once

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>

#include "fusion/grid/occupancy_grid.h"
#include "fusion/grid_lines/grid_line_extractor.h"
#include "fusion/lines/scan_lines.h"
#include "server/events/event_hub.h"
#include "server/json/codec.h"
#include "rules/engine.h"
#include "server/service/prolog_worker.h"
#include "server/service/rules_watcher.h"
#include "server/storage/store.h"
#include "server/world/update.h"

namespace wm::service {

struct ServiceOptions {
  world::WorldOptions world;
  std::size_t max_queued_requests = 256;
  /// Watch the rules directory and reload on change (nullopt: reload only on request).
  std::optional<std::filesystem::path> watch_rules_dir;
  /// Decisions the knowledge base keeps as decision/7 facts (the full log is in SQLite).
  std::size_t decision_facts_kept = 10000;
  /// At most this many elements pruned per update.
  std::size_t max_prune_per_update = 1000;
  /// Occupancy grids (both models); the resolution of a stored grid wins over this one.
  fusion::GridOptions grid;
  /// Changed grid tiles are written at most this often (every scan is journaled at once; scans after the
  /// last flush are replayed at start).
  std::chrono::milliseconds grid_flush_interval{1000};
  /// Laser scans also go through the scan line extractor; its segments are decided like posted primitives
  /// (origin "scan", sensor "laser").
  bool extract_scan_lines = true;
  fusion::ScanLineOptions scan_lines;
  /// Run the grid line extractor (thinning + Hough) every this many scans (0: only on request), and its settings.
  std::size_t grid_extract_every = 0;
  fusion::GridLineOptions grid_lines;
};

/// One re-decided observation of a dry run whose decision differs.
struct DryRunChange {
  world::DecisionRecord recorded;  // as it was decided and logged
  rules::Decision candidate;       // what the candidate rules answer to the same question
};

struct DryRunOutcome {
  std::size_t redecided = 0;
  std::vector<DryRunChange> changes;
};

/// Owns the world model. One writer thread applies every change (match → rules → apply → store) in
/// arrival order; readers take immutable snapshots that are swapped after each committed request, so
/// they never block the writer and never see half an update. Prolog decisions run on the writer thread;
/// knowledge-base queries and dry runs run on a second Prolog thread, so a slow query never holds up
/// ingest. The knowledge base mirrors the committed map: objects, elements, recent decisions.
class WorldService {
 public:
  /// Starts the writer with the state loaded from `store`. @throw storage::StorageError, rules::RuleError.
  /// `events` (optional) receives what changed after every commit, for live clients.
  WorldService(const ServiceOptions& options, storage::Store& store, rules::Engine& engine,
               events::EventHub* events = nullptr);
  ~WorldService();
  WorldService(const WorldService&) = delete;
  WorldService& operator=(const WorldService&) = delete;

  std::shared_ptr<const world::WorldState> snapshot() const;
  const ServiceOptions& options() const { return options_; }
  storage::Store& store() { return store_; }

  struct PrimitivesOutcome {
    std::int64_t seq = 0;
    std::int64_t version = 0;
    std::vector<world::DecisionRecord> decisions;
  };
  /// Applies one request whole or not at all, and returns after it is committed.
  /// @throw Busy, storage::StorageError, std::exception from the update (nothing applied then).
  PrimitivesOutcome post_primitives(world::Observation observation, std::string payload_json);
  /// Replaces the floor plan (store and knowledge base facts). Returns the new map version.
  std::int64_t load_floor_plan(apriori::FloorPlan plan);

  rules::RulesStatus rules_status();
  /// Reloads the rule files atomically. @throw rules::RuleError ("file:line: message" lines); the previous
  /// rules stay active then.
  rules::RulesStatus reload_rules();
  struct ScanOutcome {
    std::int64_t seq = 0;          // journal sequence of the scan
    std::int64_t grid_revision = 0;  // scans inserted into the grid so far (this one included)
    std::optional<PrimitivesOutcome> lines;  // the decisions on the lines extracted from it, if any
  };
  /// Journals the scan and inserts it into both grids. @throw Busy, storage::StorageError.
  ScanOutcome post_scan(json_codec::ScanRequest scan, std::string payload_json);
  /// Runs `read(grid)` under a shared lock: concurrent readers, never during an insert.
  template <typename F>
  auto read_grid(F&& read) const {
    std::shared_lock lock(grid_mutex_);
    return read(*grid_);
  }
  std::int64_t grid_revision() const { return grid_revision_.load(); }

  /// Converts the Bayes grid into line segments (threshold, thinning, Hough, fits with eq. 3 covariance) and
  /// decides them like posted primitives (origin "grid"). nullopt when the grid is empty or yields no line.
  std::optional<PrimitivesOutcome> extract_grid_lines();

  /// Read-only knowledge-base query. @throw rules::QueryError, Busy.
  rules::QueryResult query(const std::string& goal, std::size_t max_solutions);
  /// Re-decides the last `count` logged segment decisions with `candidate` in place of the file of its
  /// name, and returns those whose action or rule would differ. Each is asked the question it was asked
  /// then (same match): later observations are not replayed against a map that would have diverged.
  /// @throw rules::RuleError when the candidate does not load; std::invalid_argument for a bad name.
  DryRunOutcome dry_run(const rules::RuleText& candidate, std::size_t count);

 private:
  void publish(world::WorldState state);
  std::vector<rules::ObjectFacts> object_facts(const world::WorldState& state) const;
  void sync_all_facts(const world::WorldState& state);
  void on_rules_changed();
  void insert_scan(const json_codec::ScanRequest& scan);
  PrimitivesOutcome apply_on_writer(world::Observation observation, const std::string& payload);
  std::optional<PrimitivesOutcome> extract_grid_lines_on_writer();
  void flush_grid(bool force);
  void emit(const nlohmann::json& event);

  const ServiceOptions options_;
  storage::Store& store_;
  rules::Engine& engine_;
  events::EventHub* events_;

  mutable std::mutex snapshot_mutex_;
  std::shared_ptr<const world::WorldState> snapshot_;

  mutable std::shared_mutex grid_mutex_;
  std::unique_ptr<fusion::OccupancyGrid> grid_;  // changed on the writer thread only
  std::atomic<std::int64_t> grid_revision_{0};
  std::int64_t last_scan_seq_ = 0;
  std::int64_t flushed_scan_seq_ = 0;
  bool flush_all_tiles_ = false;
  std::chrono::steady_clock::time_point last_flush_ = std::chrono::steady_clock::now();

  // Declared last: destroyed first, so their threads stop before the members they use go away.
  std::unique_ptr<PrologWorker> writer_;
  std::unique_ptr<PrologWorker> reader_;
  std::unique_ptr<RulesWatcher> watcher_;
};

}  // namespace wm::service
