#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <shared_mutex>
#include <stdexcept>
#include <string_view>

#include "common/diagnostics.h"
#include "fusion/grid/beam_crossings.h"
#include "fusion/grid/occupancy_grid.h"
#include "fusion/grid_lines/grid_line_extractor.h"
#include "fusion/lines/scan_lines.h"
#include "fusion/registration/scan_alignment.h"
#include "pipeline/network.h"
#include "rules/engine.h"
#include "server/events/event_hub.h"
#include "server/json/codec.h"
#include "server/json/robots_json.h"
#include "server/service/event_log.h"
#include "server/service/grid_store.h"
#include "server/service/ingest_pipeline.h"
#include "server/service/map_writer.h"
#include "server/service/plan_checks.h"
#include "server/service/plan_commands.h"
#include "server/service/rules_commands.h"
#include "server/service/snapshot_log.h"
#include "server/service/world_port.h"
#include "server/storage/store.h"
#include "server/world/grid_trim.h"
#include "server/world/plan_evidence.h"
#include "server/world/update.h"

namespace wm::service {

/// The service's parts, each with its own options.
struct ServiceOptions {
  /// Deciding observations against the map: matching, the decisions the rules keep as facts, pruning.
  MapWriterOptions map;
  /// The ingest network, scan lines and their alignment, grid lines, the grid trim.
  IngestOptions ingest;
  /// Occupancy grids (both models; the resolution of a stored grid wins), tile flushes, beam counts at the plan.
  GridStoreOptions grids;
  /// The plan's edges checked against the grid, and the changes listed.
  PlanChecksOptions plan_checks;
  /// Watch the rules directory and reload on change (nullopt: reload only on request).
  std::optional<std::filesystem::path> watch_rules_dir;
};

/// Owns the world model, as a few parts with one job each: the map writer (decide, commit, publish an observation),
/// the ingest pipeline (scans and primitives on the processing network, the grid trim), the plan commands (load,
/// place, align and edit the plan, accept changes), the rules commands (reload, query, dry run), the grid store, the
/// plan checks, the robots and the events of each commit. This class builds them in order at start (the grid and
/// robots from the journal, the knowledge base from the map), runs every change as a command on the ingest's writer
/// thread, and answers reads from the published snapshot, which never blocks on the writers. Knowledge-base queries
/// and dry runs run on their own Prolog thread.
class WorldService final : public WorldPort {
 public:
  /// Starts the writer with the state loaded from `store`. @throw storage::StorageError, rules::RuleError.
  /// `diagnostics` hears of what the service handles without failing a request (a flush retried, a rules edit
  /// rejected by the watcher) and must outlive it; `events` (optional) receives what changed after every commit, for
  /// live clients.
  WorldService(const ServiceOptions& options, storage::Store& store, rules::Engine& engine,
               common::Diagnostics& diagnostics, events::EventHub* events = nullptr);
  ~WorldService();
  WorldService(const WorldService&) = delete;
  WorldService& operator=(const WorldService&) = delete;

  const ServiceOptions& options() const { return options_; }

  std::shared_ptr<const world::WorldState> snapshot() const override;
  const world::WorldOptions& world_options() const override { return options_.map.world; }

  /// Applies one request whole or not at all, and returns after it is committed.
  ///
  /// `request_id` (optional, from the client): the first request with it is applied and its id is committed
  /// in the same transaction; a later one with the same id and the same body (`payload_json`, byte for byte)
  /// is not applied again but answered as the first was (same seq, version and decisions, replayed = true),
  /// as long as the id is among the last StoreOptions::request_ids_kept. A request that fails stores nothing,
  /// so its retry is applied.
  /// @throw Busy, storage::StorageError, std::exception from the update (nothing applied then);
  /// RequestIdConflict for a known id with another body or from the scans endpoint.
  PrimitivesOutcome post_primitives(world::Observation observation, std::string payload_json,
                                    std::optional<std::string> request_id) override;
  /// Applies a scan whole or not at all: the lines extracted from a laser scan are decided first, then the
  /// scan's journal entry, the observation of its lines with every decision and change, and the request id
  /// commit in one transaction; only then is the scan inserted into both grids (whose tiles are flushed
  /// lazily: the journal is the grid's source of truth and is replayed past the last flush at start).
  /// `request_id` as for post_primitives. @throw Busy, storage::StorageError (nothing applied then),
  /// RequestIdConflict.
  ScanOutcome post_scan(world::ScanObservation scan, std::string payload_json,
                        std::optional<std::string> request_id) override;
  /// A batch of scans: each as post_scan, all of them decided one after another and committed in one transaction
  /// (one fsync); a failure applies none of them.
  std::vector<ScanOutcome> post_scans(std::vector<world::ScanObservation> scans, std::string_view body,
                                      std::optional<std::string> request_id) override;
  /// Replaces the floor plan (store and knowledge base facts). Returns the new map version.
  std::int64_t load_floor_plan(apriori::FloorPlan plan) override;
  PlacementOutcome place_floor_plan(world::PlacementChange change, std::string payload_json) override;
  AlignOutcome align_floor_plan(AlignRequest request) override;
  PlacementOutcome undo_placement(std::string observer) override;
  RedecideOutcome redecide_elements(std::string observer) override;
  std::int64_t set_georeference(std::optional<apriori::Georeference> georeference) override;
  /// Converts the Bayes grid into line segments (threshold, thinning, Hough, fits with eq. 3 covariance) and
  /// decides them like posted primitives (origin "grid"). nullopt when the grid is empty or yields no line.
  std::optional<PrimitivesOutcome> extract_grid_lines() override;

  rules::RulesStatus rules_status() override;
  /// Reloads the rule files atomically. @throw rules::RuleError ("file:line: message" lines); the previous
  /// rules stay active then.
  rules::RulesStatus reload_rules() override;
  /// Read-only knowledge-base query. @throw rules::QueryError, Busy.
  rules::QueryResult query(const std::string& goal, std::size_t max_solutions) override;
  /// Re-decides the last `count` logged segment decisions with `candidate` in place of the file of its
  /// name, and returns those whose action or rule would differ. Each is asked the question it was asked
  /// then (same match): later observations are not replayed against a map that would have diverged.
  /// @throw rules::RuleError when the candidate does not load; std::invalid_argument for a bad name.
  DryRunOutcome dry_run(const rules::RuleText& candidate, std::size_t count) override;

  std::vector<world::DecisionRecord> decisions(std::int64_t since_seq, std::size_t limit,
                                               const std::optional<std::string>& element) override;
  std::vector<world::DecisionRecord> object_decisions(const std::string& object_id, std::size_t limit) override;

  double grid_resolution_m() const override;
  std::optional<fusion::GridGeometry> grid_bounds() const override;
  GridLayerValues grid_layer(fusion::GridLayer layer, const fusion::GridGeometry& region) const override;
  GridSonarStatus grid_sonar() const override;
  GridTiles grid_tiles() const override;
  std::optional<GridTileValues> grid_tile_layers(std::int64_t tx, std::int64_t ty) const override;
  std::optional<GridTileValues> grid_tile(fusion::GridLayer layer, std::int64_t tx, std::int64_t ty) const override;
  /// Scans in the grid: the journal sequence of the last one inserted.
  std::int64_t grid_revision() const { return grid_.revision(); }
  /// The processing network's components, ports, queues and activity.
  pipeline::NetworkStats network_stats() const override;
  pipeline::NetworkStats set_network_subtask(const std::string& name, bool running) override;
  pipeline::NetworkStats set_network_params(const std::string& component,
                                            const std::map<std::string, std::string>& changes) override;
  std::optional<MapRemovals> removed_since(std::int64_t since, std::int64_t up_to) const override;
  /// The plan's edges against the grid and the rules' verdicts on them, as of the last grid check.
  std::shared_ptr<const world::PlanReport> plan_report() const override;
  /// Checks the whole plan against the grid now, on the writer (what a grid trim does for the region its scans saw),
  /// and returns the new report: for tools that score the evidence at the end of a drive.
  std::shared_ptr<const world::PlanReport> refresh_plan_report();
  std::vector<world::Change> changes(std::shared_ptr<const world::WorldState>& state,
                                     std::shared_ptr<const world::PlanReport>& evidence) const override;
  /// On the writer: accepts (a new plan, committed with its decision and the plan before it, for undo) or rejects a
  /// listed change. @throw NotFound, storage::StorageError, std::invalid_argument from the plan edit.
  ChangeOutcome decide_change(const std::string& change_id, bool accept, std::string observer) override;
  ChangeOutcome undo_change(std::string observer) override;
  std::vector<RobotState> robots() const override { return robots_.list(); }
  std::optional<RobotState> robot(const std::string& id) const override { return robots_.find(id); }
  RobotState put_robot_pose(const std::string& id, RobotPose pose, bool stopped) override;
  const RobotOptions& robot_options() const override { return robots_.options(); }
  /// Whether the network processes this sensor's scans ("laser", "sonar").
  bool accepts_scans(const std::string& sensor) const;

 private:
  /// Runs `work` on the writer thread when nothing is in flight. @throw Busy when the queue is full.
  template <typename F>
  auto run_command(F&& work) -> decltype(work()) {
    return ingest_->run_command(std::forward<F>(work));
  }

  const ServiceOptions options_;
  storage::Store& store_;
  rules::Engine& engine_;
  common::Diagnostics& diagnostics_;
  EventLog event_log_;  // the commits' live events, in commit order
  MapWriter writer_;    // the published map
  RobotRegistry robots_;
  GridStore grid_;          // inserted on the grid thread (and at start, before the ingest runs)
  PlanChecks plan_checks_;  // refreshed on the writer

  // Declared last: destroyed first, so their threads stop before the members they use go away (also when the
  // constructor throws after the network started).
  std::unique_ptr<IngestPipeline> ingest_;
  std::unique_ptr<PlanCommands> plan_;    // runs on ingest_'s writer
  std::unique_ptr<RulesCommands> rules_;  // reloads on ingest_'s writer; queries on a Prolog thread of its own
};

}  // namespace wm::service
