#pragma once

#include <Eigen/Core>

#include "fusion/geometry/line.h"
#include "fusion/grid/grid_geometry.h"
#include "fusion/grid_lines/internal/raster_lines.h"

// Between a raster's centred cell frame (CellLine) and the world frame; not part of the public API.
namespace wm::fusion::internal {

/// World position [m] of the raster's centre (the origin of the centred cell frame).
Eigen::Vector2d raster_center_m(const GridGeometry& geometry);

/// World position [m] of a point given in centred cells.
Eigen::Vector2d world_point(const GridGeometry& geometry, double xc, double yc);

/// The world line [m] of a centred-cell line, normalized, with zero covariance.
LineFeature world_line(const CellLine& line, const GridGeometry& geometry);

/// The centred-cell line of a world line (covariance ignored).
CellLine cell_line(const LineFeature& line, const GridGeometry& geometry);

}  // namespace wm::fusion::internal
