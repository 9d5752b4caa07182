#pragma once

// What the HTTP handlers, the Foxglove bridge and the shared-memory export may ask of the world-model service, and
// nothing more: six ports (map, ingest, plan, rules, grid, robots) of under ten methods each. They see no store, no
// knowledge base, no writer thread, no grid lock. WorldService implements all six (WorldPort); a test fakes only the
// ports it uses. The ports live with the service (not the api) so that the dependency arrows stay one-way
// (api → service → world, storage, rules) and the contract sits beside its implementation.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "apriori/floor_plan.h"
#include "fusion/grid/grid_geometry.h"
#include "fusion/grid/laser_sonar_grids.h"
#include "fusion/grid/occupancy_grid.h"
#include "fusion/registration/plan_registration.h"
#include "pipeline/network.h"
#include "rules/types.h"
#include "server/service/robot_registry.h"
#include "server/service/service_errors.h"
#include "server/world/changes.h"
#include "server/world/plan_evidence.h"
#include "server/world/scan_observation.h"
#include "server/world/update.h"

namespace wm::service {

/// What an accept, reject or undo of a change did.
struct ChangeOutcome {
  std::int64_t version = 0;        // the map version after it
  world::DecisionRecord decision;  // as logged
  std::string change_id;
  std::optional<std::string> added_object;  // a new wall accepted: its object's id in the plan
};

/// What an applied (or replayed) observation answered.
struct PrimitivesOutcome {
  std::int64_t seq = 0;                          // the observation's journal sequence
  std::int64_t version = 0;                      // the map version after it
  std::vector<world::DecisionRecord> decisions;  // one per segment, in order
  bool replayed = false;  // the answer of an earlier request with the same request id; nothing applied now
};

/// Where the server placed a laser scan: the sensor pose posted, and the one its lines and beams took (the same
/// unless the scan was aligned to the map's lines).
struct ScanPlacement {
  fusion::Pose2D posted;
  fusion::Pose2D placed;
  bool aligned() const {
    return placed.x_m != posted.x_m || placed.y_m != posted.y_m || placed.theta_rad != posted.theta_rad;
  }
};

struct ScanOutcome {
  std::int64_t seq = 0;                    // journal sequence of the scan
  std::int64_t grid_revision = 0;          // scans ever inserted into the grid (this one included); = seq
  std::optional<PrimitivesOutcome> lines;  // the decisions on the lines extracted from it, if any
  bool replayed = false;                   // as for PrimitivesOutcome
  std::optional<ScanPlacement> placement;  // a laser scan's, when scan lines are extracted
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

/// A placement of the plan put in force.
struct PlacementOutcome {
  std::int64_t version = 0;
  world::DecisionRecord decision;  // the `place` decision with before/after
};

/// What re-deciding the observed elements against the plan did.
struct RedecideOutcome {
  std::size_t elements = 0;                      // elements put to the rules
  std::int64_t version = 0;                      // map version after (unchanged when nothing changed)
  std::vector<world::DecisionRecord> decisions;  // the decisions that changed the map (kept elements: none)
};

struct AlignRequest {
  fusion::RegistrationOptions search;  // `initial` is set by the service to the placement in force
  bool scale_given = false;            // else the scale in force is kept
  bool apply = false;                  // put the best placement in force when it is good and not ambiguous
  bool apply_ambiguous = false;        // ... even when it is ambiguous
  double min_score = 0.5;              // below this share of the seen plan on occupied cells, nothing is applied
  double min_coverage = 0.05;          // nor when less than this share of the plan lies in the observed area
  bool redecide = false;               // after applying, re-decide the observed elements
  std::string observer = "client";
};

struct AlignOutcome {
  fusion::RegistrationResult result;
  fusion::Similarity2D before;
  bool applied = false;
  std::string verdict;  // "applied", or why not: "preview", "ambiguous", "low_score", "low_coverage", "timed_out"
  std::optional<PlacementOutcome> placement;
  std::optional<RedecideOutcome> redecided;
  std::size_t edges = 0;  // drawn edges searched (solid objects' when the plan marks any)
};

/// The cells of one grid layer over a region, with the grid revision they were read at.
struct GridLayerValues {
  std::vector<float> values;  // row-major from the lower-left cell; NaN = unknown
  std::int64_t revision = 0;  // scans in the grid when it was read
};

/// The grid's tiles: tile (tx, ty) holds cells [tx·T, (tx+1)·T) × [ty·T, (ty+1)·T), cell (0, 0) having its lower-left
/// corner at the world origin; `revision` counts the inserts that changed it (its content is the same while it is).
struct GridTileRevision {
  std::int64_t tx = 0;
  std::int64_t ty = 0;
  std::uint64_t revision = 0;
};
struct GridTiles {
  std::int64_t tile_size_cells = 0;
  double resolution_m = 0;
  std::int64_t revision = 0;  // scans in the grid
  std::vector<GridTileRevision> tiles;
};
/// The sonar side of the grids: seen at all, judged by the laser (the option), and the gate's verdicts so far.
struct GridSonarStatus {
  bool seen = false;
  bool gated = true;
  fusion::SonarGateCounts counts;
};
/// One tile of one layer (tile_size² values, row-major from its lower-left cell, NaN unknown) and its revision.
struct GridTileValues {
  std::vector<float> values;
  std::uint64_t revision = 0;
};

/// The ids that left the map between two versions (GET /api/v1/map?since=).
struct MapRemovals {
  std::set<std::string> elements;  // "e<number>"
  std::set<std::string> objects;   // CAD object ids
};

// The world-model service as the HTTP handlers, the Foxglove bridge and the shared-memory export see it, in six
// ports of one job each, so that a handler (and its test's fake) depends on what it uses. Every call is safe from
// any thread. Writes are applied whole or not at all, in arrival order, and return after they are committed; reads
// never wait for the writer.

/// The committed map and its logs: snapshots, decisions, removals, the plan's evidence and the change list.
class MapPort {
 public:
  virtual ~MapPort() = default;

  /// The committed world: an immutable snapshot, swapped after each applied request.
  virtual std::shared_ptr<const world::WorldState> snapshot() const = 0;
  virtual const world::WorldOptions& world_options() const = 0;

  /// The decision log: decisions with seq > since_seq, in order, at most `limit`; only those about `element`
  /// (an element or edge id) when given. @throw storage::StorageError.
  virtual std::vector<world::DecisionRecord> decisions(std::int64_t since_seq, std::size_t limit,
                                                       const std::optional<std::string>& element) = 0;
  /// Decisions about a CAD object or any of its edges ("table-1/2"), in order, at most `limit`.
  /// @throw storage::StorageError.
  virtual std::vector<world::DecisionRecord> object_decisions(const std::string& object_id, std::size_t limit) = 0;
  /// What left the map after version `since` up to version `up_to` (a snapshot's), nullopt when the service no
  /// longer knows: `since` is older than the removals it keeps (the newest 100 000 ids) or than its start.
  virtual std::optional<MapRemovals> removed_since(std::int64_t since, std::int64_t up_to) const = 0;

  /// The plan's edges against the occupancy grid (backed, seen through, observed) and the rules' verdicts on them
  /// (missing walls, objects gone), as of the last grid check. Never null; empty without a plan or a grid.
  virtual std::shared_ptr<const world::PlanReport> plan_report() const {
    return std::make_shared<const world::PlanReport>();
  }

  /// The changes between plan and building (world::list_changes over the snapshot and the plan report), without
  /// those a person rejected.
  virtual std::vector<world::Change> changes(std::shared_ptr<const world::WorldState>& state,
                                             std::shared_ptr<const world::PlanReport>& evidence) const {
    state = snapshot();
    evidence = plan_report();
    return world::list_changes(*state, evidence.get(), world::ChangeOptions{});
  }
};

/// What robots and clients post: primitives and scans, grid lines on request, and the network they run on.
class IngestPort {
 public:
  virtual ~IngestPort() = default;

  /// Applies one primitives request. `payload_json` is the request body, journaled as is. `request_id`
  /// (Idempotency-Key, optional): a retry with the same id and the same body is answered as the first was
  /// (replayed = true) without being applied again.
  /// @throw Busy; RequestIdConflict for a known id with another body or from the scans endpoint;
  ///        storage::StorageError; std::invalid_argument from the update (nothing applied in every case).
  virtual PrimitivesOutcome post_primitives(world::Observation observation, std::string payload_json,
                                            std::optional<std::string> request_id) = 0;
  /// Journals a scan with the decisions on its extracted lines, then inserts it into the grids. `request_id`
  /// as for post_primitives. @throw Busy, RequestIdConflict, storage::StorageError (nothing applied then).
  virtual ScanOutcome post_scan(world::ScanObservation scan, std::string payload_json,
                                std::optional<std::string> request_id) = 0;
  /// Applies the scans of one request body whole or not at all, in one transaction, and answers one outcome per scan
  /// in order. `body` is hashed for the request ids: scan i is recorded under `<request_id>[i]`, and a retry of the
  /// same body is answered scan by scan without being applied again. @throw as post_scan, for the whole batch.
  virtual std::vector<ScanOutcome> post_scans(std::vector<world::ScanObservation> scans, std::string_view body,
                                              std::optional<std::string> request_id) {
    (void)scans, (void)body, (void)request_id;
    throw Conflict("this service takes no batches of scans");
  }
  /// Runs the grid line extractor on the Bayes layer and decides its segments like posted primitives.
  /// nullopt when the grid is empty or yields no line. @throw Busy, storage::StorageError.
  virtual std::optional<PrimitivesOutcome> extract_grid_lines() = 0;
  /// The processing network the writes run on: components, ports, queue depths, activity.
  virtual pipeline::NetworkStats network_stats() const = 0;
  /// Starts or stops a subtask of the network while it runs; returns the network as it is then.
  /// @throw NotFound for an unknown subtask, Busy while the network stops.
  virtual pipeline::NetworkStats set_network_subtask(const std::string& name, bool running) {
    (void)name, (void)running;
    throw Conflict("this service's network has no subtasks");
  }
  /// Changes parameters of a component while the network runs (text values, checked as in a task file); returns
  /// the network as it is then. @throw NotFound for an unknown component; std::invalid_argument for a parameter
  /// that cannot change or a bad value (nothing changed); Busy while the network stops.
  virtual pipeline::NetworkStats set_network_params(const std::string& component,
                                                    const std::map<std::string, std::string>& changes) {
    (void)component, (void)changes;
    throw Conflict("this service's network takes no parameters");
  }
};

/// The floor plan: loading, placement, alignment, re-deciding against it, georeference, and accepting changes.
class PlanPort {
 public:
  virtual ~PlanPort() = default;

  /// Replaces the floor plan; the observed elements stay. Returns the new map version.
  /// @throw Busy, storage::StorageError, std::invalid_argument for bad geometry.
  virtual std::int64_t load_floor_plan(apriori::FloorPlan plan) = 0;
  /// Puts a placement of the plan in force (one logged `place` decision; objects keep their pose relative to the
  /// drawing). `payload_json` is journaled. @throw Conflict without a plan, Busy, storage::StorageError.
  virtual PlacementOutcome place_floor_plan(world::PlacementChange change, std::string payload_json) = 0;
  /// Searches the placement that fits the grid best, and applies it when asked and it is sound.
  /// @throw Conflict without a plan or with an empty grid, fusion::RegistrationError for bad bounds, Busy.
  virtual AlignOutcome align_floor_plan(AlignRequest request) = 0;
  /// Goes back to the placement before the one in force. @throw Conflict when the plan is as drawn.
  virtual PlacementOutcome undo_placement(std::string observer) = 0;
  /// Puts every observed element to the rules against the plan as placed now: elements the plan confirms go,
  /// merges and rigid adjustments are applied; elements the rules would add again stay as they are.
  virtual RedecideOutcome redecide_elements(std::string observer) = 0;
  /// Sets (or, with nullopt, removes) the world frame's georeference. Returns the new map version.
  virtual std::int64_t set_georeference(std::optional<apriori::Georeference> georeference) = 0;

  /// Accepts a listed change into the plan (a new version of the plan; the decision is logged) or rejects it (no
  /// longer listed; logged). @throw NotFound when `change_id` is not listed now; storage::StorageError.
  virtual ChangeOutcome decide_change(const std::string& change_id, bool accept, std::string observer) {
    (void)change_id, (void)accept, (void)observer;
    throw Conflict("this service does not take changes");
  }
  /// Undoes the last accept (the plan before it is back) or reject (the change is listed again).
  /// @throw Conflict when nothing is left to undo.
  virtual ChangeOutcome undo_change(std::string observer) {
    (void)observer;
    throw Conflict("this service does not take changes");
  }
};

/// The knowledge base: its rule files, queries and dry runs.
class RulesPort {
 public:
  virtual ~RulesPort() = default;

  virtual rules::RulesStatus rules_status() = 0;
  /// Reloads the rule files atomically. @throw rules::RuleError ("file:line: message" lines; the previous rules
  /// stay active), Busy.
  virtual rules::RulesStatus reload_rules() = 0;
  /// Read-only knowledge-base query. @throw rules::QueryError, Busy.
  virtual rules::QueryResult query(const std::string& goal, std::size_t max_solutions) = 0;
  /// Re-decides the last `count` logged segment decisions with `candidate` in place of the file of its name;
  /// returns those whose action or rule would differ. Nothing is applied.
  /// @throw rules::RuleError when the candidate does not load; std::invalid_argument for a bad name; Busy.
  virtual DryRunOutcome dry_run(const rules::RuleText& candidate, std::size_t count) = 0;
};

/// The occupancy grid: its cells, layers and tiles.
class GridPort {
 public:
  virtual ~GridPort() = default;

  /// The grid's cell size [m].
  virtual double grid_resolution_m() const = 0;
  /// The cells observed so far, nullopt while the grid is empty.
  virtual std::optional<fusion::GridGeometry> grid_bounds() const = 0;
  /// One layer over `region` (cells never observed are NaN), read under the grid's shared lock: never during an
  /// insert, and a waiting insert goes first.
  virtual GridLayerValues grid_layer(fusion::GridLayer layer, const fusion::GridGeometry& region) const = 0;
  /// Every touched tile with its revision, read under one lock.
  virtual GridTiles grid_tiles() const = 0;
  /// One tile of a layer with its revision, read under one lock; nullopt for a tile never touched.
  virtual std::optional<GridTileValues> grid_tile(fusion::GridLayer layer, std::int64_t tx, std::int64_t ty) const = 0;
  /// Every layer of one tile, in Layer order (tile_size² values each, one after the other), read under one lock so
  /// all four are of one revision; nullopt for a tile never touched.
  virtual std::optional<GridTileValues> grid_tile_layers(std::int64_t tx, std::int64_t ty) const = 0;
  /// Whether sonar was seen and is judged by the laser, and what the gate did so far.
  virtual GridSonarStatus grid_sonar() const = 0;
};

/// The robots heard from.
class RobotPort {
 public:
  virtual ~RobotPort() = default;

  /// The robots heard from (scans, primitives, reported poses), by id; restored from the journal at start.
  virtual std::vector<RobotState> robots() const = 0;
  virtual std::optional<RobotState> robot(const std::string& id) const = 0;
  /// Journals a pose a robot reports without a scan (odometry, a localiser), then applies it.
  /// @throw storage::StorageError (nothing applied then).
  virtual RobotState put_robot_pose(const std::string& id, RobotPose pose, bool stopped) = 0;
  virtual const RobotOptions& robot_options() const = 0;
};

/// The whole service: what wmd wires in (WorldService implements it).
class WorldPort : public virtual MapPort,
                  public virtual IngestPort,
                  public virtual PlanPort,
                  public virtual RulesPort,
                  public virtual GridPort,
                  public virtual RobotPort {};

/// The six ports of one service, as the handlers get them.
struct WorldPorts {
  MapPort& map;
  IngestPort& ingest;
  PlanPort& plan;
  RulesPort& rules;
  GridPort& grid;
  RobotPort& robots;

  WorldPorts(WorldPort& world)  // NOLINT(google-explicit-constructor): every port of one service
      : map(world), ingest(world), plan(world), rules(world), grid(world), robots(world) {}
  WorldPorts(MapPort& m, IngestPort& i, PlanPort& p, RulesPort& r, GridPort& g, RobotPort& b)
      : map(m), ingest(i), plan(p), rules(r), grid(g), robots(b) {}
};

}  // namespace wm::service
