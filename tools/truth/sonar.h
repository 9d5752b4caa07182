#pragma once

// A sonar ring on the truth benchmark's robot, and what judging sonar by the laser does to the fused grid's walls.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "fusion/grid/laser_sonar_grids.h"
#include "fusion/grid/scan.h"
#include "tools/truth/world.h"

namespace wm::truth {

/// A ring of Polaroid 6500-class transducers (docs/fusion.md §8): a 30° cone each, the first echo within it.
/// Specular reflection (Kuc and Siegel's model of a smooth wall: it echoes back only near its normal): a ray of the
/// cone returns only when it meets a surface within specular_limit_deg of the surface's normal; people (diffuse)
/// always echo. When no ray of the cone returns, the axis ray is followed through one mirror bounce: if it then
/// meets a surface near its normal, the echo comes back the same way and the reading is the whole path (a long
/// reading, farther than any wall in the cone); else there is no echo (range_max). Cross talk: with probability
/// cross_talk a transducer hears a neighbour's echo first, a reading uniform in [range_min, true reading).
struct SonarOptions {
  int transducers = 16;  // evenly around the robot
  double beam_width_deg = 30;
  double specular_limit_deg = 15;  // incidence beyond which a smooth wall sends no echo back
  double ray_step_deg = 1;         // rays across the cone
  double cross_talk = 0.05;
  double range_min_m = 0.15;
  double range_max_m = 6.0;  // the Polaroid's practical reach indoors
  double sigma_range_m = 0.02;
  double sigma_per_range = 0.01;
};

/// What each reading is, by construction.
enum class SonarTruth { echo, specular_long, specular_lost, cross_talk };

struct SonarRing {
  fusion::SonarScan scan;        // posted at the laser scan's (noisy) pose
  std::vector<SonarTruth> kind;  // per transducer
};

/// The ring at each pose of the drive (at its true pose, posted at the pose the drive's laser scan was posted at;
/// `laser` is what the drive was made with: where the people are at each scan).
std::vector<SonarRing> sonar_drive(const BuiltWorld& world, const Drive& drive, const LaserOptions& laser,
                                   const SonarOptions& options, unsigned seed);

/// The walls and the free space of one grid against the world as built.
struct GridWallScore {
  std::size_t wall_cells = 0;   // cells on true lines occupied in the laser-only grid (what the laser mapped)
  std::size_t walls_kept = 0;   // of those, occupied in this grid
  std::size_t false_cells = 0;  // occupied cells farther than 0.15 m from every true line (people's paths aside)
  std::size_t free_cells = 0;   // cells free (P < 0.25) in this grid
  double kept_share() const { return wall_cells ? static_cast<double>(walls_kept) / wall_cells : 1.0; }
};

struct SonarFusionResult {
  std::string building;
  std::size_t scans = 0, readings = 0;
  std::size_t specular = 0, cross_talk = 0;  // readings of each kind, by construction
  fusion::SonarGateCounts gate;              // the gate's verdicts in the gated run
  std::size_t cross_talk_dropped = 0;        // cross-talk readings the gate dropped as phantoms
  std::size_t cross_talk_clipped = 0;        // ... or clipped (their hit removed: a surface the laser sees is nearer)
  std::size_t cross_talk_kept = 0;           // ... or kept: a laser-seen surface lies in their arc
  std::size_t echoes_dropped = 0;            // true echoes it dropped (glass-like mistakes: should be few)
  GridWallScore laser_only, gated, ungated;
};

/// Drives the building (as built with its default edits, people included), feeds the laser scans and the sonar ring
/// of each pose into a gated and an ungated LaserSonarGrids, and scores both fused grids and the laser-only grid.
/// `max_route_m` > 0 drives only that much. @throw std::runtime_error as load_building.
SonarFusionResult run_sonar_fusion(const std::string& building, const std::filesystem::path& data_dir, unsigned seed,
                                   double max_route_m = 0, const SonarOptions& sonar = {});

std::string format_sonar_table(const std::vector<SonarFusionResult>& results);

}  // namespace wm::truth
