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
#include "server/service/plan_checks.h"
#include "server/service/prolog_worker.h"
#include "server/service/rules_watcher.h"
#include "server/service/snapshot_log.h"
#include "server/service/world_port.h"
#include "server/storage/store.h"
#include "server/world/grid_trim.h"
#include "server/world/plan_evidence.h"
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
  /// A laser scan posted with a pose covariance is first aligned to the map's lines (fusion::align_scan_lines): its
  /// lines, its grid beams, its journal entry and its robot take the corrected pose. They keep the posted covariance:
  /// the lines are fused into the very elements they were aligned to, and a covariance narrowed by those elements
  /// would count what they know twice (on the CARMEN logs the narrowed one left more elements per wall and a worse
  /// calibration).
  bool align_scans = true;
  fusion::ScanAlignmentOptions scan_alignment;
  /// Run the grid line extractor (thinning + Hough) every this many scans (0: only on request), and its settings.
  std::size_t grid_extract_every = 0;
  fusion::GridLineOptions grid_lines;
  /// Every this many scans, the ends of the elements the scans since the last time could see are cut back to
  /// what the Bayes grid backs (world::trim_to_grid, its own observation of origin "grid"); 0: never.
  std::size_t grid_trim_every = 10;
  world::GridTrimOptions grid_trim;
  /// How the plan's edges are checked against the grid (at every grid trim, where its scans could see, and over the
  /// whole plan at start and when the plan or its placement changes).
  world::PlanEvidenceOptions plan_evidence;
  /// How the beams of laser scans are counted at the plan's edges (passed through, ended on).
  fusion::BeamCrossingOptions beam_crossings;
  /// Which differences between plan and building are listed as changes.
  world::ChangeOptions changes;
  /// The processing network the ingest runs on (a YAML task file; nullopt: the built-in default network).
  std::optional<std::filesystem::path> network_file;
};

/// The default processing network (its YAML task file): matcher, store, grid and grid lines each on their own
/// executor.
std::string default_network_yaml();

/// Now, in seconds since the Unix epoch (when an observation was received).
double now_unix_s();

/// Owns the world model. Writes run on a processing network (pipeline::Network, from a task file): the matcher
/// decides scans' lines and posted primitives against the map as the requests before them leave it (match → rules
/// → apply), the store commits what arrives together in one transaction, the grid inserts committed scans; every
/// other change (plan, placement, rules, extraction, trims) is a command the matcher runs when nothing is in flight.
/// A request is answered after the transaction that holds it commits (a scan after it is in the grid too). Readers
/// take immutable snapshots that are swapped after each committed request, so they never block the writers and
/// never see half an update. Knowledge-base queries and dry runs run on their own Prolog thread. The knowledge base
/// follows the decided map (and goes back to the committed one when a commit fails).
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
  const world::WorldOptions& world_options() const override { return options_.world; }

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
  GridLayerValues grid_layer(fusion::OccupancyGrid::Layer layer, const fusion::GridGeometry& region) const override;
  GridTiles grid_tiles() const override;
  std::optional<GridTileValues> grid_tile_layers(std::int64_t tx, std::int64_t ty) const override;
  std::optional<GridTileValues> grid_tile(fusion::OccupancyGrid::Layer layer, std::int64_t tx,
                                          std::int64_t ty) const override;
  /// Scans in the grid: the journal sequence of the last one inserted.
  std::int64_t grid_revision() const { return grid_.revision(); }
  /// The processing network's components, ports, queues and activity.
  pipeline::NetworkStats network_stats() const override;
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
  void on_rules_changed();
  /// The robots as the journal left them (at start).
  void restore_robots();
  /// Adds a robot's new pose or status to the commit (`live`; nothing when `robot` is nullopt: no event due).
  void add_robot_event(EventLog::Commit& live, const std::optional<RobotState>& robot);
  /// An observation decided and applied in memory (the rules' facts already follow it), not yet committed.
  struct PreparedUpdate {
    std::shared_ptr<const world::WorldState> base;  // the state it was decided against
    world::Observation observation;
    world::UpdateResult update;
    std::int64_t seq = 0;
  };
  PreparedUpdate prepare_update(world::Observation observation);
  /// An observation the server makes itself (grid trim, placement, redecide) against `base`, numbered next; its
  /// update is the caller's to fill.
  static PreparedUpdate own_observation(std::shared_ptr<const world::WorldState> base, std::string observer,
                                        std::string origin, std::string sensor);
  /// Runs `commit`; if it throws, puts the rules' facts back to the committed map and rethrows.
  void commit_prepared(const PreparedUpdate& prepared, const std::function<void()>& commit);
  /// After the commit: publishes the new state, tells the rules, and adds the update event to the commit (`live`).
  PrimitivesOutcome finish_update(PreparedUpdate prepared, EventLog::Commit& live,
                                  std::set<std::string> removed_objects = {});
  PrimitivesOutcome apply_on_writer(world::Observation observation, const std::string& payload);
  static std::int64_t body_hash(std::string_view body);
  /// The stored record of `request_id` when it was used before (nullopt: apply the request).
  /// @throw RequestIdConflict when it was used with another body or kind.
  std::optional<storage::RequestRecord> known_request(const std::string& request_id, std::string_view kind,
                                                      std::int64_t body_hash);
  std::optional<PrimitivesOutcome> extract_grid_lines_on_writer();
  /// On the writer: applies and commits a placement (`undo`: pops the stack instead of pushing).
  PlacementOutcome place_on_writer(const world::PlacementChange& change, const std::string& payload, bool undo);
  RedecideOutcome redecide_on_writer(const std::string& observer);

  // The steps of post_scan, in order, on the writer thread.
  /// The first answer to a scan retried with its request id; nullopt: apply it. @throw RequestIdConflict.
  std::optional<ScanOutcome> replayed_scan(const std::optional<std::string>& request_id, std::int64_t body_hash,
                                           const world::ScanObservation& retried);
  /// The lines of a laser scan, extracted and decided against the head map (nothing stored yet); nullopt for a
  /// sonar scan, with scan lines off, or when no line is found. A scan aligned to the map (align_scans) leaves with
  /// its corrected sensor pose; `placement` says where it was placed.
  std::optional<PreparedUpdate> prepare_scan_lines(world::ScanObservation& scan,
                                                   std::optional<ScanPlacement>& placement);
  /// Adds the live "scan" event to its commit (`live`): the robot's pose, where its beams returned and the grid
  /// region that changed.
  void add_scan_event(EventLog::Commit& live, const world::ScanObservation& scan, std::int64_t seq);
  /// Publishes an event of `kind` as a commit of its own (when anyone listens; its JSON only when someone reads it).
  void emit(events::EventKind kind, const std::function<nlohmann::json()>& make_json) {
    event_log_.publish(kind, make_json);
  }

  // The processing network (world_service_network.cpp).
  struct Decided;
  struct GridScan;
  using DecidedPtr = std::shared_ptr<Decided>;
  using GridScanPtr = std::shared_ptr<GridScan>;
  struct TrimTick {
    std::int64_t scan_seq = 0;
    world::Box region;             // what the scans since the last trim (scan_seq − every, scan_seq] could see
    std::shared_ptr<void> ticket;  // the scan that made the trim due is answered after it
  };
  pipeline::Registry network_registry();
  /// Runs `work` on the matcher when nothing is in flight, and returns its result. @throw Busy when the queue is full.
  template <typename F>
  auto run_command(F&& work) -> decltype(work()) {
    using Result = decltype(work());
    auto task = std::make_shared<std::packaged_task<Result()>>(std::forward<F>(work));
    auto future = task->get_future();
    submit_command([task] { (*task)(); });
    return future.get();
  }
  void submit_command(std::function<void()> job);
  /// The map the next request is decided against: the last one decided (committed or in flight).
  std::shared_ptr<const world::WorldState> head() const;
  /// At the start of each decision on the matcher: the head is the published map when nothing is in flight.
  void refresh_head();
  /// The matcher's functions.
  void decide_scan(pipeline::Activation& a, const std::string& port);
  void decide_primitives(pipeline::Activation& a);
  void commit_group(pipeline::Activation& a);
  void finish_committed(pipeline::Activation& a);
  void insert_grid_scans(pipeline::Activation& a, bool laser, bool sonar, std::int64_t extract_every);
  /// The grid trim of what the scans since the last one could see, decided against head() (nullopt: nothing to do).
  std::optional<PreparedUpdate> prepare_trim(const world::Box& region);
  /// The trim due at scan `scan_seq` (a multiple of grid_trim_every), decided and committed on the writer; at start,
  /// when the journal ends at such a scan and its trim was not stored (a crash between the two commits).
  void trim_now(std::int64_t scan_seq, const world::Box& region);
  /// The grid trim's observer and the payload of its observation (what says at start that a trim was stored).
  static constexpr const char* kTrimObserver = "grid-trim";
  static std::string trim_payload(std::int64_t scan_seq) {
    return "{\"grid_revision\": " + std::to_string(scan_seq) + "}";
  }
  /// Grows the trim region by what scan `scan` could see. @throw from the scan geometry.
  void add_to_trim_region(const world::ScanObservation& scan);
  void decide_trim(pipeline::Activation& a);
  /// After a failed group commit: what was decided on top of it is dropped, the rules go back to the committed map.
  void resync_after_failure();

  // Matcher thread only:
  std::shared_ptr<const world::WorldState> head_;
  std::int64_t next_scan_seq_ = 0;                           // the last scan decided (journaled or in flight)
  std::int64_t committed_scan_seq_ = 0;                      // the last scan committed
  std::uint64_t epoch_ = 1;                                  // requests decided since the last failed commit
  std::map<std::string, std::int64_t> pending_request_ids_;  // in flight: id → body hash
  std::atomic<std::size_t> in_flight_{0};                    // decided, not yet finished
  std::atomic<std::uint64_t> failed_epoch_{0};               // the store failed a group of this epoch
  mutable std::mutex trim_mutex_;
  const ServiceOptions options_;
  storage::Store& store_;
  rules::Engine& engine_;
  common::Diagnostics& diagnostics_;
  EventLog event_log_;  // the commits' live events, in commit order

  RobotRegistry robots_;
  SnapshotLog published_;                  // the committed map, what each version removed
  GridStore grid_;                         // inserted on the grid thread (and at start, before the network runs)
  PlanChecks plan_checks_;                 // refreshed on the writer
  std::atomic<bool> aligning_{false};      // an align_floor_plan search is running
  std::optional<world::Box> trim_region_;  // what the scans since the last grid trim could see (trim_mutex_)

  // Declared last: destroyed first, so their threads stop before the members they use go away (also when the
  // constructor throws after the network started).
  std::unique_ptr<pipeline::Network> network_;
  std::unique_ptr<PrologWorker> reader_;
  std::unique_ptr<RulesWatcher> watcher_;
};

}  // namespace wm::service
