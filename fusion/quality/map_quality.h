#pragma once

#include <cstddef>
#include <span>

#include "fusion/geometry/line.h"
#include "fusion/grid/grid_geometry.h"

namespace wm::fusion {

/// How a vector map is scored against an occupancy raster (the Bayes grid of the same data). The defaults are the
/// figures the project reports (README "Map quality").
struct MapQualityOptions {
  double sample_step_m = 0.02;                 // elements are sampled this often along their extent, > 0
  double occupied_probability = 0.65;          // a raster cell with P above this is occupied, in (0, 1)
  double recall_radius_m = 0.10;               // an occupied cell is explained when an element passes this close, > 0
  double redundancy_offset_m = 0.05;           // a sample lies on another element within this distance ...
  double redundancy_angle_rad = 0.0872664626;  // ... whose direction differs by at most this (5°), in [0, π/2]
};

/// The figures. Lengths are of element extents (t1 − t0).
struct MapQuality {
  std::size_t elements = 0;
  double total_length_m = 0;
  double median_length_m = 0;
  double elements_per_m = 0;  // elements / total length; 0 for an empty map
  /// Share of element length (sampled every sample_step_m) within one cell (the 3×3 neighbourhood) of an occupied
  /// cell: how much of the map is backed by the grid. 0 for an empty map.
  double precision = 0;
  /// Share of occupied cells whose centre lies within recall_radius_m of an element: how much of the grid the
  /// map explains. 0 when the raster has no occupied cell.
  double recall = 0;
  /// Share of element length lying within redundancy_offset_m of a different element's extent that runs within
  /// redundancy_angle_rad of the same direction: the same wall kept twice counts here. 0 for an empty map.
  double redundancy = 0;
  std::size_t occupied_cells = 0;
};

/// Scores `elements` against a dense raster of occupancy probabilities (row-major from the lower-left cell of
/// `raster`, NaN = unknown, as OccupancyGrid::export_layer gives the Bayes layer). Cost: linear in the sampled
/// length and the raster's cells; redundancy looks only at elements in nearby buckets of a uniform hash grid.
/// @throw std::invalid_argument when probabilities.size() != width·height or an option is out of range.
MapQuality map_quality(std::span<const LineSegment> elements, const GridGeometry& raster,
                       std::span<const float> probabilities, const MapQualityOptions& options = {});

}  // namespace wm::fusion
