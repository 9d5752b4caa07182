#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "fusion/grid/grid_geometry.h"
#include "fusion/grid/occupancy_grid.h"

namespace wm::fusion {

/// Largest raster the grid line extractor accepts [cells]: 2^28, so that every (padded) pixel index fits in 32 bits.
inline constexpr std::int64_t kMaxRasterCells = std::int64_t{1} << 28;

/// A dense occupancy-probability raster with its geometry: p[y·width + x] is the occupancy probability of cell
/// (x, y), row-major from the lower-left cell (the layout of OccupancyGrid::export_layer); NaN marks an unknown
/// cell. Invariant (checked by validate()): p.size() == width·height <= kMaxRasterCells, every known value in [0, 1].
struct ProbabilityRaster {
  GridGeometry geometry;
  std::vector<float> p;
};

/// @throw std::invalid_argument when p.size() differs from width·height, the raster has more than kMaxRasterCells
///        cells, or a value is infinite or outside [0, 1] (NaN is allowed: unknown).
void validate(const ProbabilityRaster& raster);

/// The Bayes probability layer of `grid` over `region` (OccupancyGrid::export_layer).
/// @throw std::invalid_argument when the region has more than OccupancyGrid::kMaxExportCells cells.
ProbabilityRaster probability_raster(const OccupancyGrid& grid, const GridGeometry& region);

/// The Bayes probability layer over every touched tile (grid.bounds()); nullopt for an empty grid.
/// @throw std::invalid_argument when the bounds have more than OccupancyGrid::kMaxExportCells cells.
std::optional<ProbabilityRaster> probability_raster(const OccupancyGrid& grid);

}  // namespace wm::fusion
