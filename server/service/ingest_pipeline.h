#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/diagnostics.h"
#include "fusion/grid_lines/grid_line_extractor.h"
#include "fusion/lines/scan_lines.h"
#include "fusion/registration/scan_alignment.h"
#include "pipeline/network.h"
#include "rules/engine.h"
#include "server/service/event_log.h"
#include "server/service/grid_store.h"
#include "server/service/map_writer.h"
#include "server/service/plan_checks.h"
#include "server/service/robot_registry.h"
#include "server/service/world_port.h"
#include "server/storage/store.h"
#include "server/world/grid_trim.h"
#include "server/world/scan_continuations.h"

namespace wm::service {

struct IngestOptions {
  std::size_t max_queued_requests = 256;
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
  /// A laser scan also gives views of the map's elements past their ends from returns too sparse for the extractor
  /// (world::scan_continuations): a wall seen only at a grazing angle from afar, 0.5–1 m between returns, grows
  /// along the line it is known to lie on. They are decided with the scan's own lines. false: no such views.
  bool continue_lines = true;
  fusion::LineContinuationOptions line_continuation;
  /// Run the grid line extractor (thinning + Hough) every this many scans (0: only on request), and its settings.
  std::size_t grid_extract_every = 0;
  fusion::GridLineOptions grid_lines;
  /// Every this many scans, the ends of the elements the scans since the last time could see are cut back to
  /// what the Bayes grid backs (world::trim_to_grid, its own observation of origin "grid"); 0: never.
  std::size_t grid_trim_every = 10;
  world::GridTrimOptions grid_trim;
  /// The processing network the ingest runs on (a YAML task file; nullopt: the built-in default network).
  std::optional<std::filesystem::path> network_file;
};

/// The default processing network (its YAML task file): matcher, store, grid and grid lines each on their own
/// executor.
std::string default_network_yaml();

/// The parts of the service the ingest writes through; each must outlive the pipeline.
struct IngestParts {
  storage::Store& store;
  rules::Engine& engine;
  MapWriter& writer;
  GridStore& grid;
  PlanChecks& plan_checks;
  RobotRegistry& robots;
  EventLog& events;
  common::Diagnostics& diagnostics;
};

/// Adds a robot's new pose or status to a commit's events (`live`; nothing when `robot` is nullopt: no event due).
void add_robot_event(EventLog::Commit& live, const RobotRegistry& robots, const std::optional<RobotState>& robot);

/// The ingest: scans and primitives decided, committed and put into the grids on a processing network
/// (pipeline::Network, from a task file). The matcher decides scans' lines, posted primitives and the grid trims
/// against the map as the requests before them leave it (match → rules → apply), the store commits what arrives
/// together in one transaction, the grid inserts committed scans. Whatever else changes the map (the service's plan,
/// placement, rules and changes, a grid line extraction asked for) runs as a command on the matcher when nothing is
/// in flight. A request is answered after the transaction that holds it commits (a scan after it is in the grid
/// too). A scan's path, stage by stage, is written out in ingest_pipeline.cpp.
class IngestPipeline {
 public:
  /// Rebuilds the grid trim's region from the journal (the grid must hold every journaled scan) and starts the
  /// network. @throw storage::StorageError reading the journal, pipeline errors for a bad task file.
  IngestPipeline(const IngestOptions& options, IngestParts parts);
  /// Stops the network if stop() did not.
  ~IngestPipeline();
  /// Runs what is queued (commands included) and stops the network; values left in its queues are reported (their
  /// requests got 503). Called before the parts the commands use go away; a second call does nothing.
  void stop();
  IngestPipeline(const IngestPipeline&) = delete;
  IngestPipeline& operator=(const IngestPipeline&) = delete;

  const IngestOptions& options() const { return options_; }

  /// See WorldService::post_scan and post_primitives. @throw Busy, storage::StorageError, RequestIdConflict,
  /// std::invalid_argument for a sensor the network does not take.
  ScanOutcome post_scan(world::ScanObservation scan, std::string payload_json, std::optional<std::string> request_id);
  PrimitivesOutcome post_primitives(world::Observation observation, std::string payload_json,
                                    std::optional<std::string> request_id);
  /// See WorldService::post_scans: the scans are decided one after another with nothing between them, go to the
  /// store as one value (so into one transaction, with whatever else is waiting) and are answered in order.
  std::vector<ScanOutcome> post_scans(std::vector<world::ScanObservation> scans, std::string_view body,
                                      std::optional<std::string> request_id);
  /// Runs `work` on the matcher when nothing is in flight, and returns its result. @throw Busy when the queue is full.
  template <typename F>
  auto run_command(F&& work) -> decltype(work()) {
    using Result = decltype(work());
    auto task = std::make_shared<std::packaged_task<Result()>>(std::forward<F>(work));
    auto future = task->get_future();
    submit_command([task] { (*task)(); });
    return future.get();
  }
  /// In a command: decides, commits and publishes an observation of the server's own (`payload` as stored).
  PrimitivesOutcome apply(world::Observation observation, const std::string& payload);
  /// In a command: the grid line extractor over the whole grid, its lines decided like posted primitives (origin
  /// "grid"). nullopt when the grid is empty or yields no line.
  std::optional<PrimitivesOutcome> extract_grid_lines();
  /// The observation of the grid line extractor's lines, and its payload (the grid revision it was run at).
  static world::Observation grid_lines_observation(const std::vector<fusion::LineSegment>& segments);
  static std::string grid_lines_payload(std::int64_t grid_revision) {
    return "{\"grid_revision\": " + std::to_string(grid_revision) + "}";
  }
  /// In a command, once at start: the grid trim a crash between a scan and the trim it made due left undone.
  void trim_left_undone();

  /// Whether the network processes this sensor's scans ("laser", "sonar").
  bool accepts_scans(const std::string& sensor) const;
  pipeline::NetworkStats stats() const;
  /// See pipeline::Network::set_subtask and set_params. @throw NotFound for an unknown name, Busy while stopping,
  /// std::invalid_argument (set_params) for a parameter that cannot change or a bad value.
  void set_subtask(const std::string& name, bool running);
  void set_params(const std::string& component, const std::map<std::string, std::string>& changes);

  /// FNV-1a, 64 bits, of a request body: tells a retry (same bytes) from a reuse of its id for another body.
  static std::int64_t body_hash(std::string_view body);

 private:
  struct Decided;
  struct GridScan;
  struct ScanJob;
  struct ScanBatch;
  using ScanJobPtr = std::shared_ptr<ScanJob>;
  using ScanBatchPtr = std::shared_ptr<ScanBatch>;
  using DecidedPtr = std::shared_ptr<Decided>;
  using GridScanPtr = std::shared_ptr<GridScan>;
  struct TrimTick {
    std::int64_t scan_seq = 0;
    world::Box region;             // what the scans since the last trim (scan_seq − every, scan_seq] could see
    std::shared_ptr<void> ticket;  // the scan that made the trim due is answered after it
  };

  pipeline::Registry network_registry();
  void submit_command(std::function<void()> job);

  // The stages, in a scan's order (ingest_pipeline.cpp).
  void decide_scan(pipeline::Activation& a, const std::string& port);
  void decide_scan_batch(pipeline::Activation& a);
  /// Decides one scan against the head map, which it becomes, and puts it in flight. @throw from its lines' decision
  /// (nothing changed then).
  DecidedPtr decide_scan_job(ScanJobPtr job, std::int64_t body_hash);
  void decide_primitives(pipeline::Activation& a);
  void decide_trim(pipeline::Activation& a);
  void commit_group(pipeline::Activation& a);
  void finish_committed(pipeline::Activation& a);
  void finish_decided(pipeline::Activation& a, DecidedPtr d);
  void insert_grid_scans(pipeline::Activation& a, bool laser, bool sonar, std::int64_t extract_every);
  /// After a failed group commit: what was decided on top of it is dropped, the rules go back to the committed map.
  void resync_after_failure();

  // What the stages do (ingest_stages.cpp).
  /// The map the next request is decided against: the last one decided (committed or in flight).
  std::shared_ptr<const world::WorldState> head() const;
  /// At the start of each decision on the matcher: the head is the published map when nothing is in flight.
  void refresh_head();
  /// The stored record of `request_id` when it was used before (nullopt: apply the request).
  /// @throw RequestIdConflict when it was used with another body or kind.
  std::optional<storage::RequestRecord> known_request(const std::string& request_id, std::string_view kind,
                                                      std::int64_t body_hash);
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
  /// Grows the trim region by what scan `scan` could see. @throw from the scan geometry.
  void add_to_trim_region(const world::ScanObservation& scan);
  /// The grid trim of what the scans since the last one could see, decided against head() (nullopt: nothing to do).
  std::optional<PreparedUpdate> prepare_trim(const world::Box& region);
  /// The trim due at scan `scan_seq` (a multiple of grid_trim_every), decided and committed on the writer.
  void trim_now(std::int64_t scan_seq, const world::Box& region);
  /// The views of the map's elements past their ends that a laser scan's sparse returns give (world frame, the
  /// scan at its placed pose); `local` are its own lines in the sensor's frame.
  std::vector<world::ScanContinuation> continuations(const fusion::LaserScan& laser,
                                                     const std::vector<fusion::LineSegment>& local,
                                                     const fusion::ScanLineOptions& line_options,
                                                     const Eigen::Matrix3d& pose_cov) const;
  /// The grid trim's observer and the payload of its observation (what says at start that a trim was stored).
  static constexpr const char* kTrimObserver = "grid-trim";
  static std::string trim_payload(std::int64_t scan_seq) {
    return "{\"grid_revision\": " + std::to_string(scan_seq) + "}";
  }

  const IngestOptions options_;
  storage::Store& store_;
  rules::Engine& engine_;
  MapWriter& writer_;
  /// Scans taken off the grid's queues and waiting for the ones before them (grid executor thread only).
  std::map<std::int64_t, GridScanPtr> grid_held_;
  static constexpr std::size_t kMaxHeldGridScans = 4096;
  GridStore& grid_;
  PlanChecks& plan_checks_;
  RobotRegistry& robots_;
  EventLog& events_;
  common::Diagnostics& diagnostics_;
  bool stopped_ = false;

  // Matcher thread only:
  std::shared_ptr<const world::WorldState> head_;
  std::int64_t next_scan_seq_ = 0;                           // the last scan decided (journaled or in flight)
  std::int64_t committed_scan_seq_ = 0;                      // the last scan committed
  std::uint64_t epoch_ = 1;                                  // requests decided since the last failed commit
  std::map<std::string, std::int64_t> pending_request_ids_;  // in flight: id → body hash
  std::optional<std::pair<std::int64_t, world::Box>> trim_left_undone_;  // found at start, made by trim_left_undone

  std::atomic<std::size_t> in_flight_{0};       // decided, not yet finished
  std::atomic<std::uint64_t> failed_epoch_{0};  // the store failed a group of this epoch
  mutable std::mutex trim_mutex_;
  std::optional<world::Box> trim_region_;  // what the scans since the last grid trim could see (trim_mutex_)

  // Declared last: destroyed first, so its threads stop before the members they use go away.
  std::unique_ptr<pipeline::Network> network_;
};

}  // namespace wm::service
