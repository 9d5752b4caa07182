#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>

#include "server/world/spatial_hash.h"
#include "server/world/update.h"

namespace wm::world {

/// What the occupancy grid says about one point of an element.
enum class GridEvidence {
  backed,    // an occupied cell within one cell of the point
  contrary,  // seen, but no occupied cell within one cell: free space, or too little evidence of a surface
  unknown,   // no cell within one cell has been seen
};
using GridProbe = std::function<GridEvidence(const Eigen::Vector2d&)>;

struct GridTrimOptions {
  double step_m = 0.05;      // sample spacing along an element (the grid's cell size) [m], > 0
  double min_trim_m = 0.04;  // cut nothing shorter than this from an element [m] (0.04: one sample at 5 cm)
  double min_kept_m = 0.10;  // an element whose backed part is shorter is left whole (removal is the rules') [m]
};

/// What the grid said of one element at a check, over the extent it keeps (the whole element when it is not cut):
/// shares of its samples.
struct GridShares {
  std::int64_t number = 0;
  double backed = 0, contrary = 0;  // [0, 1]; the rest is unknown to the grid
};

struct GridTrimResult {
  UpdateResult update;              // the trims (no decisions: nothing changed)
  std::vector<GridShares> checked;  // every element looked at, trimmed or not
};

/// Cuts the ends of the elements near `region` back to what the grid backs. From each end, the samples the grid
/// has seen but does not back are dropped up to the first backed sample; an unknown sample stops the cut (the grid
/// says nothing there, e.g. a client that posts lines without scans). The line, its covariance and its moments
/// stay: only the extent changes. Why: an element's extent is the union of everything fused into it, so one view
/// that ran past a wall's end (a door frame, a chair beside it) keeps the element reaching into space that
/// every later scan sees through. Each cut is a "trim" decision of `observation_seq` with the old and new
/// endpoints in before/after ([x0, y0, x1, y1]). `current` is not changed. Elements shorter than two samples are
/// not looked at; elements of origin "client" are looked at (their shares are reported) but never cut.
GridTrimResult trim_to_grid(const WorldState& current, const Box& region, const GridProbe& probe,
                            std::int64_t observation_seq, const std::string& observer, const GridTrimOptions& options);

}  // namespace wm::world
