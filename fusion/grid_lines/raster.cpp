#include "fusion/grid_lines/raster.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace wm::fusion {

void validate(const ProbabilityRaster& raster) {
  const std::int64_t width = raster.geometry.width();
  const std::int64_t height = raster.geometry.height();
  // width, height <= 10^6 (GridGeometry), so the product cannot overflow.
  if (width * height > kMaxRasterCells) {
    throw std::invalid_argument("validate(ProbabilityRaster): " + std::to_string(width) + " x " +
                                std::to_string(height) + " cells exceed the limit of 2^28");
  }
  if (static_cast<std::int64_t>(raster.p.size()) != width * height) {
    throw std::invalid_argument("validate(ProbabilityRaster): p has " + std::to_string(raster.p.size()) +
                                " values for " + std::to_string(width) + " x " + std::to_string(height) + " cells");
  }
  for (std::size_t i = 0; i < raster.p.size(); ++i) {
    const float v = raster.p[i];
    if (std::isnan(v)) continue;
    if (!(v >= 0.0f && v <= 1.0f)) {
      throw std::invalid_argument("validate(ProbabilityRaster): p[" + std::to_string(i) + "] = " + std::to_string(v) +
                                  " is outside [0, 1]");
    }
  }
}

ProbabilityRaster probability_raster(const OccupancyGrid& grid, const GridGeometry& region) {
  return {region, grid.export_layer(OccupancyGrid::Layer::bayes_probability, region)};
}

std::optional<ProbabilityRaster> probability_raster(const OccupancyGrid& grid) {
  const std::optional<GridGeometry> bounds = grid.bounds();
  if (!bounds) return std::nullopt;
  return probability_raster(grid, *bounds);
}

}  // namespace wm::fusion
