#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "fusion/grid/occupancy_grid.h"
#include "fusion/grid/scan.h"
#include "fusion/grid/sensor_model.h"

namespace wm::fusion {

/// Sonar judged by the laser (docs/fusion.md §8): where a laser-only grid has seen the cells a sonar cone covers, the
/// laser, the more reliable sensor, decides whether a sonar reading can be true before it reaches the fused grid.
///  - A *phantom* (cross talk, a multi-path echo): the laser saw the return's arc, widened by band_margin_m either
///    side, free (at least phantom_seen_share of its cells below free_probability), no cell of it is occupied, and
///    no return of the latest laser scans lies in it (a person who just stepped into space the grid holds free is
///    in the laser's scan before the grid calls the cell occupied). The reading is dropped: no hit, no free space.
///  - A *long* reading (specular reflection: at grazing incidence the pulse bounces away and the echo, if any,
///    comes from farther away; a "no return" is the same): the cone's free space runs into a cell the laser holds
///    occupied. The reading is clipped: free space up to clip_margin_m in front of the first such cell, no hit, so
///    the sonar never erodes a wall the laser sees.
///  - Otherwise the reading is kept as it is: the laser agrees (an occupied cell in the return's band) or has not
///    seen enough of the arc to judge (*unjudged*: a sonar-only place, e.g. below a table the laser sees over).
/// What the gate cannot know: a surface only sonar sees where the laser has seen free space (glass, a low shelf in
/// the laser's plane's blind band) is removed as a phantom. Maps with such surfaces turn the gate off.
struct SonarGateOptions {
  double free_probability = 0.25;      // a laser cell is free below this (three laser misses), (0, 0.5)
  double occupied_probability = 0.65;  // and occupied above this (the map-quality definition), (0.5, 1)
  double phantom_seen_share = 0.9;     // share of the return's arc the laser must have seen free, (0, 1]
  double band_margin_m = 0.10;         // the return's band widened by this either side [m], >= 0 (pose error)
  double clip_margin_m = 0.10;         // free space stops this far in front of a laser-occupied cell [m], >= 0
};

/// @throw std::invalid_argument naming the first field outside its range.
void validate(const SonarGateOptions& options);

enum class SonarVerdict {
  kept,      // the laser agrees with the reading (an occupied cell in its band), nothing in its cone contradicts it
  unjudged,  // the laser has not seen enough of the return's arc; kept as it is
  phantom,   // dropped
  clipped,   // free space shortened to stop in front of a laser-seen surface, hit removed
  ignored,   // the reading is not one (NaN, below range_min): sonar_beam skips it anyway
};
const char* to_string(SonarVerdict verdict);

struct SonarGateResult {
  /// Beam i as the fused grid takes it (OccupancyGrid::insert(scan, beams)); nullopt: nothing of it goes in.
  std::vector<std::optional<Beam>> beams;
  std::vector<SonarVerdict> verdicts;  // per beam
  std::size_t count(SonarVerdict verdict) const;
};

/// Judges every reading of `scan` against `laser_grid` (a grid that only laser scans went into), with the sensor
/// model of `laser_grid`'s options. Deterministic: depends only on the scan and the laser grid's cells.
/// @throw std::invalid_argument when the scan or the options are invalid.
/// `recent_returns`: the return points of the latest laser scans (world frame [m]); any of them in a return's band
/// backs it.
SonarGateResult gate_sonar(const SonarScan& scan, const OccupancyGrid& laser_grid, const SonarGateOptions& options,
                           const std::vector<Eigen::Vector2d>& recent_returns = {});

}  // namespace wm::fusion
