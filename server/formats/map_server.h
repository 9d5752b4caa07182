#pragma once

// The ROS map_server (Nav2 map_io) pair for an occupancy layer: a binary PGM image and the map.yaml that places
// it. The server's other map file formats (DXF, GeoJSON) are written by apriori/export/.
#include <string>
#include <vector>

#include "fusion/grid/grid_geometry.h"

namespace wm::formats {

/// Occupied above, free below these probabilities (map_server's trinary mode); unknown cells are written
/// between them.
inline constexpr double kOccupiedThreshold = 0.65;
inline constexpr double kFreeThreshold = 0.196;
/// The pixel value of an unknown cell: occupancy (255 − 205) / 255 = 0.196…0.65, read as unknown.
inline constexpr int kUnknownPixel = 205;

/// A binary PGM (P5) of `values` (P(occupied) per cell, row-major from the region's lower-left cell, NaN =
/// unknown): pixel 255·(1 − p) with negate 0, unknown 205, top row first (PGM rows run from the largest y). A
/// comment line states the origin and resolution [m], so one file is enough to place it.
/// @throw std::invalid_argument when values.size() is not the region's cell count.
std::string pgm_image(const std::vector<float>& values, const fusion::GridGeometry& region);

/// The map.yaml for the PGM of `region`: image map.pgm beside it, mode trinary, the resolution [m/cell],
/// origin = the region's lower-left corner [m] with yaw 0, negate 0 and the two thresholds above.
std::string map_yaml(const fusion::GridGeometry& region);

}  // namespace wm::formats
