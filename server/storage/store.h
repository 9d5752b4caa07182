#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fusion/grid/beam_crossings.h"
#include "fusion/grid/occupancy_grid.h"
#include "server/storage/database.h"
#include "server/storage/leases.h"
#include "server/world/scan_observation.h"
#include "server/world/update.h"

namespace wm::storage {

struct StoreOptions {
  /// A SQLite file (created when missing), or a PostgreSQL database's URI (postgresql://user@host:port/db?...;
  /// a password in a file: PGPASSFILE, or PGPASSWORD in the environment, never on a command line).
  std::string path;
  /// synchronous=FULL makes every acknowledged request survive a power loss (one fsync per commit,
  /// ~0.3 ms here); NORMAL survives process crashes only.
  bool synchronous_full = true;
  /// Request ids (Idempotency-Key) remembered: the newest this many; older ones are forgotten, and a retry
  /// that late is applied again. At ~100 bytes a row, 100 000 ids cost ~10 MB.
  std::int64_t request_ids_kept = 100000;
  /// PostgreSQL only: the schema that holds this map's tables (created when missing, with PostGIS in `public`).
  std::string postgres_schema = "worldmodel";
  /// PostgreSQL only, in a cluster: the map's lease this store writes under (leases.h); every write transaction
  /// checks it and throws FencedError, committing nothing, once it is no longer held.
  std::optional<Fence> fence = std::nullopt;
};

/// What a request that carried a client-supplied request id produced, kept (in the same transaction as its
/// effect) so that a retry is answered the same without being applied again.
struct RequestRecord {
  std::string request_id;
  std::string kind;                       // "primitives" or "scan"
  std::int64_t body_hash = 0;             // of the request body, to refuse the same id with another body
  std::int64_t seq = 0;                   // primitives: the observation; scan: the scan's journal sequence
  std::int64_t version = 0;               // the map version after the observation (a scan: after its lines; 0 without)
  std::int64_t grid_revision = 0;         // scan only
  std::optional<std::int64_t> lines_seq;  // scan only: the observation of its extracted lines, if any
};

/// One placement of the plan as stored: the stack's rows, oldest first.
struct StoredPlacement {
  fusion::Similarity2D placement;
  Eigen::Matrix4d cov = Eigen::Matrix4d::Zero();
  std::string rule;
  std::int64_t decision_seq = 0;
};

/// One scan for the journal, kept in its binary form (scan_record.h): what is replayed into the grid at start.
struct ScanEntry {
  std::int64_t seq = 0;  // = the grid revision it brings the grid to (one more than the last journaled scan)
  const world::ScanObservation* scan = nullptr;  // not null; must outlive the commit
};

/// A journaled scan as start-up reads it: the scan, or for a row stored before scans were kept in binary form, the
/// JSON request body it came in (the caller parses that with the wire codec).
struct JournaledScan {
  std::int64_t seq = 0;
  std::optional<world::ScanObservation> scan;
  std::string legacy_json;  // only when scan is nullopt
};

/// An observation and what applying it changed, to be written together.
struct ObservationEntry {
  const world::UpdateResult& update;
  const world::Observation& observation;
  std::string_view payload;
};

/// The world model's database: a SQLite file (WAL; the embedded default) or a schema of a PostgreSQL database (its
/// elements and objects also as PostGIS geometries, for GIS tools). The same SQL for both; schema versioned (SQLite:
/// PRAGMA user_version; PostgreSQL: table schema_version) with forward migrations.
/// Writes are serialised on one connection, one transaction per applied request or group; decision-log reads use
/// their own connection and may come from any thread.
class Store {
 public:
  /// Opens or creates the file and migrates it. @throw StorageError (also for a file newer than this build).
  explicit Store(const StoreOptions& options);

  static constexpr int kSchemaVersion = 11;
  int schema_version();
  /// Which engine holds it.
  Dialect dialect() const;
  /// The lease this store's writes are fenced by (StoreOptions::fence); nullopt when none.
  const std::optional<Fence>& fence() const { return options_.fence; }

  /// The persisted world (an empty state for a new file). @throw StorageError, apriori::FloorPlanError.
  world::WorldState load(const world::WorldOptions& options);

  /// Journals the observation and writes its effects (changed rows, decisions, counters) and the request
  /// record, when given, in one transaction. @throw StorageError (nothing written then).
  void commit_observation(const world::UpdateResult& update, const world::Observation& observation,
                          std::string_view payload_json, const std::optional<RequestRecord>& request = std::nullopt);
  /// Replaces the stored floor plan and objects in one transaction. The placement stays.
  void commit_floor_plan(const world::UpdateResult& update, const apriori::FloorPlan& plan);
  /// A change of placement: its observation, decision and moved objects, and the placement pushed on the stack
  /// (or, for an undo, the top row removed), in one transaction. @throw StorageError (nothing written then).
  void commit_placement(const ObservationEntry& entry, bool undo);
  /// The placements in force and before, oldest first (empty: the plan as drawn).
  std::vector<StoredPlacement> placements();
  /// What a person decided about a listed change between plan and building.
  struct PlanChangeRecord {
    std::string change_id;
    std::string verdict;                            // accepted | rejected
    std::optional<apriori::FloorPlan> plan_before;  // accepted: the plan the change was applied to
    std::int64_t decision_seq = 0;
  };
  /// An accept, reject or undo of a change: its observation and decision, the plan and objects when the plan changed
  /// (`plan`), and `push` on the stack of decided changes (nullopt: an undo, the top row goes), in one transaction.
  /// @throw StorageError (nothing written then).
  void commit_plan_change(const ObservationEntry& entry, const std::optional<apriori::FloorPlan>& plan,
                          const std::optional<PlanChangeRecord>& push);
  /// The decided changes, oldest first.
  std::vector<PlanChangeRecord> plan_changes();
  /// The world frame's georeference (removed when the state has none) and the counters.
  void commit_georeference(const world::WorldState& state);

  /// Decisions with seq > since_seq in order, at most `limit`; only those about `element` when given.
  std::vector<world::DecisionRecord> decisions(std::int64_t since_seq, std::size_t limit,
                                               const std::optional<std::string>& element = std::nullopt);
  /// A scan is all or nothing: its journal entry, the observation of the lines extracted from it with their
  /// decisions and effects, and the request record all commit in one transaction (the grid tiles are not
  /// written here: they are flushed later and rebuilt from this journal at start). `scan.seq` must be
  /// last_scan_seq() + 1. @throw StorageError (nothing written then).
  void commit_scan(const ScanEntry& scan, const std::optional<ObservationEntry>& lines,
                   const std::optional<RequestRecord>& request = std::nullopt);
  /// One request of a group commit: a scan (with the observation of its lines), or an observation alone.
  struct BatchEntry {
    std::optional<ScanEntry> scan;
    std::optional<ObservationEntry> observation;  // a scan's lines, or posted primitives
    std::optional<RequestRecord> request;
  };
  /// Writes every entry, in order, in one transaction (one fsync for the group): all of them or none.
  /// @throw StorageError (nothing written then).
  void commit_batch(const std::vector<BatchEntry>& entries);
  /// The sequence of the last journaled scan, 0 for none. Scans are never deleted and numbered 1, 2, …, so
  /// this is also the number of scans ever accepted: the grid revision.
  std::int64_t last_scan_seq();
  /// Whether an observation of `observer` with exactly this payload is stored (at start: was a trim stored).
  bool has_observation(const std::string& observer, const std::string& payload);

  /// A pose a robot reported without a scan (PUT /api/v1/robots/{id}/pose).
  struct RobotPoseEntry {
    std::string robot;
    double x = 0, y = 0, theta = 0;
    std::optional<Eigen::Matrix3d> cov;
    double stamp = 0;        // the robot's clock [s]
    double received_at = 0;  // the server's wall clock [s since the epoch]
    std::string state;       // "moving" | "stopped"
  };
  /// Journals one reported pose in its own transaction. @throw StorageError.
  void commit_robot_pose(const RobotPoseEntry& pose);
  /// What the journal says of each robot (an observer of scans or primitives, or a robot that reported poses), to
  /// restore the robots after a restart: counts, first and last time seen, the last scan's payload, and its newest
  /// `track_points` reported poses.
  struct RobotJournal {
    std::string robot;
    std::map<std::string, std::int64_t> scans;  // by sensor
    std::int64_t primitives = 0;
    std::int64_t poses = 0;
    double first_seen = 0, last_seen = 0;
    std::optional<JournaledScan> last_scan;  // nullopt also when its row is damaged: the robot comes back without it
    double last_scan_received_at = 0;
    std::vector<RobotPoseEntry> poses_newest_first;
  };
  std::vector<RobotJournal> robot_journal(std::size_t track_points);
  /// Journaled scans with seq > after, in order, at most `limit` of them (replayed at start past the last grid flush,
  /// a page at a time, so that a long unflushed journal is never in memory at once).
  /// @throw StorageError naming the scan when a stored scan is damaged.
  std::vector<JournaledScan> scans_after(std::int64_t after,
                                         std::size_t limit = std::numeric_limits<std::int64_t>::max());
  /// The journaled scan of `seq`; nullopt when there is none. @throw StorageError when it is damaged.
  std::optional<JournaledScan> scan(std::int64_t seq);

  /// The grid as last flushed: tiles and the last scan they include.
  /// The beams counted at one plan edge (fusion::SegmentBeams, where the edge lay when counted).
  struct StoredEdgeBeams {
    std::string object_id;
    std::int64_t edge = 0;
    fusion::SegmentBeams beams;
  };
  struct StoredGrid {
    double resolution_m = 0;
    std::int64_t tile_size_cells = 0;
    std::int64_t through_scan_seq = 0;
    std::vector<std::pair<fusion::TileIndex, fusion::OccupancyGrid::TileData>> tiles;
    std::vector<StoredEdgeBeams> edge_beams;  // changed since the last flush, through the same scan
  };
  /// nullopt when no grid was ever flushed.
  std::optional<StoredGrid> load_grid();
  /// Every plan edge's beam counts as last flushed.
  std::vector<StoredEdgeBeams> load_edge_beams();
  /// Writes changed tiles and edge beam counts and the scan sequence they include, in one transaction.
  void flush_grid(const StoredGrid& changed);

  /// The record of a request id, if it is still kept.
  std::optional<RequestRecord> find_request(const std::string& request_id);
  /// The decisions of one observation, in order.
  std::vector<world::DecisionRecord> observation_decisions(std::int64_t observation_seq);
  /// Journaled scans whose line observation is recorded but has no decision: a consistency check (0 unless
  /// the file was changed by something else than this store). Scans of files written before schema 4 whose
  /// line observation a crash lost have no recorded line observation, so they are not counted.
  std::int64_t scans_missing_line_decisions();

  /// Decisions about a CAD object (about the object or any of its edges), in order, at most `limit`.
  std::vector<world::DecisionRecord> object_decisions(const std::string& object_id, std::size_t limit);

  /// Records, in its own transaction, that the map is removed: a start that finds the mark drops what is left of it
  /// (PostgreSQL; a SQLite map's files are renamed aside instead).
  void mark_removed();
  /// Whether mark_removed ran on this database.
  bool marked_removed();

  /// The `count` newest decisions about posted segments (not prunes), oldest first.
  std::vector<world::DecisionRecord> latest_decisions(std::size_t count);

 private:
  void migrate();
  void write_counters(const world::WorldState& state);
  void write_objects(const world::UpdateResult& update);
  void insert_observation(std::int64_t seq, std::string_view kind, const std::string& observer, double stamp,
                          std::string_view payload);
  void write_observation(const ObservationEntry& entry);
  void write_request(const RequestRecord& request);
  void write_scan(const ScanEntry& scan, const std::optional<ObservationEntry>& lines);

  StoreOptions options_;
  /// The writer connection serves the group commits, the grid flushes and the commands, which may come from
  /// different threads of the processing network: one at a time, a transaction never interleaved with another.
  std::recursive_mutex writer_mutex_;
  std::unique_ptr<Connection> writer_;
  std::mutex reader_mutex_;
  std::unique_ptr<Connection> reader_;
};

}  // namespace wm::storage
