#pragma once

// The truth benchmark: a robot drives through a real building's plan as built (walls demolished, partitions added,
// the table moved, people walking), its simulated scans are replayed through an in-process world service (real
// store, real rules, no HTTP) without and with the plan, and the maps are scored against the walls as built.
#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "server/service/world_service.h"
#include "server/world/plan_evidence.h"
#include "tools/truth/world.h"

namespace wm::truth {

enum class PoseNoise { low, high };

/// "low" (σ 1 cm, 0.2°) or "high" (σ 3 cm, 0.5°).
const char* pose_noise_name(PoseNoise noise);

struct TruthOptions {
  std::filesystem::path data_dir;   // the shared real-data directory
  std::filesystem::path rules_dir;  // the knowledge base's rule files
  unsigned seed = 1;
  PoseNoise pose_noise = PoseNoise::low;
  Edits edits;
  LaserOptions laser;      // its pose σ are set from pose_noise
  double max_route_m = 0;  // 0: the whole route
  bool with_plan = true;   // also replay with the plan (the as-built figures)
  service::ServiceOptions service;
};

/// The map without a plan, against the walls as built (the table's sides count as walls; people do not).
struct MappingScore {
  double precision = 0;          // share of element length within 5 cm and 3° of a true line
  double recall = 0;             // share of the seen length (bins the beams returned from) within 5 cm of an element,
                                 // over walls at least kShortestLineM long
  double recall_all = 0;         // the same over every wall, the faces of columns and frames too
  double redundancy = 0;         // share of element length on a part of a line another element already covers
  double elements_per_wall = 0;  // elements covering ≥ 10 cm of it, over walls and partitions seen over ≥ 2 m
  std::size_t elements = 0;
  double element_length_m = 0, seen_length_m = 0,
         seen_short_m = 0;  // seen_short_m: on walls shorter than kShortestLineM
  std::size_t walls_seen_2m = 0;
  double people_element_m = 0;  // element length within 0.3 m of a person's track, on no true line [m]
};

/// The map with the plan, against the world as built.
struct AsBuiltScore {
  /// From the plan report's verdicts; nullopt while the service gives no report.
  std::optional<double> demolished_found;  // mean over demolished walls: share of the seen-through length reported
                                           // missing or partly_missing
  std::optional<double> false_missing;     // share of the length of the existing walls in view reported missing
  std::optional<double> people_missing_m;  // missing verdicts within 0.3 m of a person's track [m]
  double new_found = 0;                    // mean over partitions: share of the seen length covered by elements
  bool table_removed = false;
  double table_error_m = 0, table_error_deg = 0;  // the plan object's end pose against the true pose
  std::size_t table_edge_elements = 0;            // elements lying (by half their length) within 10 cm of its sides
  double people_element_m = 0;  // element length within 0.3 m of a person's track, on no true line [m]
};

struct TruthResult {
  std::string building;
  PoseNoise pose_noise = PoseNoise::low;
  std::size_t scans = 0;
  double route_m = 0;
  MappingScore mapping;
  std::optional<AsBuiltScore> as_built;
  double seconds = 0;  // the whole run
};

/// Loads, edits, drives, replays and scores one building. @throw std::runtime_error, and what the service throws.
TruthResult run_truth(const std::string& building, const TruthOptions& options);

/// What one replay left: the map and the plan report (nullptr when the service has none).
struct ReplayOutcome {
  std::shared_ptr<const world::WorldState> state;
  std::shared_ptr<const world::PlanReport> report;
  std::vector<std::optional<fusion::Pose2D>> placed;  // per scan: where the server placed it (none: no lines)
};

/// Posts every scan (with its noisy pose and `pose_cov`) through WorldService::post_scan in a fresh store in a
/// temporary directory, with the plan loaded first when given.
ReplayOutcome replay_scans(const std::vector<fusion::LaserScan>& scans, const Eigen::Matrix3d& pose_cov,
                           const std::optional<apriori::FloorPlan>& plan, const TruthOptions& options);

MappingScore score_mapping(const world::WorldState& state, const BuiltWorld& world, const Coverage& coverage);
AsBuiltScore score_as_built(const ReplayOutcome& outcome, const Building& building, const BuiltWorld& world,
                            const Coverage& coverage);

/// The table wm-truth prints: one row per result and a last row with the worst of each column.
std::string format_table(const std::vector<TruthResult>& results);

}  // namespace wm::truth
