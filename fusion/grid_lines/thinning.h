#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "fusion/grid_lines/raster.h"

namespace wm::fusion {

/// Binary occupancy image of a raster, row-major like raster.p: 1 where the cell is known and p >= p_occupied,
/// 0 elsewhere (free and unknown cells).
/// @throw std::invalid_argument for p_occupied not in (0, 1], or a raster that fails validate().
std::vector<std::uint8_t> threshold(const ProbabilityRaster& raster, float p_occupied);

/// Fills the small holes of a binary image (nonzero = foreground) in place: every 4-connected background
/// component of at most max_hole_pixels pixels that does not touch the image border becomes foreground. In an
/// occupancy raster these are wall cells that stayed below the threshold; left open, each would become a loop of
/// skeleton around it with spurs in every direction. Cost O(pixels).
/// @throw std::invalid_argument for width or height < 1, image.size() != width·height, more than kMaxRasterCells
///        pixels, or max_hole_pixels < 0.
void fill_small_holes(std::span<std::uint8_t> image, std::int64_t width, std::int64_t height, int max_hole_pixels);

/// One-pixel-wide skeleton of a binary image (nonzero = foreground), row-major with `width` columns, as 0/1.
///
/// Zhang & Suen (CACM 27(3), 1984): two parallel sub-iterations per pass, each marking the border pixels whose
/// 8-neighbourhood matches its table (B neighbours, one 0→1 transition, and its pair of products of 4-neighbours
/// zero), repeated until a pass deletes nothing. Three changes, all for a map rather than a picture:
///  - 3 <= B <= 6 instead of 2 <= B (Lü & Wang, CACM 29(3), 1986): with 2, the end of a 2-pixel-wide diagonal
///    stroke is deleted pass after pass until the whole stroke (a diagonal wall) is gone.
///  - A marked pixel is deleted only if, given the deletions already made in the same sub-iteration, it is still
///    8-simple (Yokoi's connectivity number 1) and not an end point. Plain Zhang–Suen deletes a 2×2 block
///    entirely, and such parallel deletions can cut thin diagonal strokes; the guard keeps every 8-connected
///    component of the input (the result is a subset with the same components, never empty where the input was
///    not).
///  - Pixels on the image border are thinned like the others (the image is treated as padded with 0), where
///    OpenCV's ximgproc::thinning leaves the border alone.
/// Only border pixels are ever examined (a list of candidates that grows by the neighbours of deleted pixels), so
/// a pass costs O(border), not O(image) as in the table-driven full scans.
/// @throw std::invalid_argument for width or height < 1, image.size() != width·height, or more than
///        kMaxRasterCells pixels.
std::vector<std::uint8_t> zhang_suen_thinning(std::span<const std::uint8_t> image, std::int64_t width,
                                              std::int64_t height);

}  // namespace wm::fusion
