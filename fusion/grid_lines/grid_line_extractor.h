#pragma once

#include <cstddef>
#include <vector>

#include "fusion/geometry/line.h"
#include "fusion/grid_lines/hough.h"
#include "fusion/grid_lines/raster.h"

namespace wm::fusion {

/// Settings of the grid line extractor. Lengths in metres are physical; bands are in cells because they follow
/// the raster's quantisation. The defaults suit 5 cm cells and walls 1–3 cells thick.
struct GridLineOptions {
  float p_occupied = 0.65f;  // cells with p >= this are occupied (threshold before thinning), (0, 1]
  /// Enclosed background specks of up to this many cells are filled before thinning (fill_small_holes), >= 0.
  int max_hole_cells = 4;
  HoughOptions hough;  // transform on the skeleton, NMS and grey-grid fallback
  /// Skeleton cells within this distance of a line belong to it [cells], [0.5, 10].
  double member_band_cells = 1.5;
  /// Occupied cells within this distance of a segment's line enter its fit [cells], [member_band_cells, 10]:
  /// the whole cross-section of a wall up to 2·fit_band thick, centred even where the skeleton is not (thinning
  /// leaves a 2-cell wall's skeleton on one of its rows).
  double fit_band_cells = 2.5;
  /// The fit cuts a segment's cells into 1-cell slices across it; a slice whose occupied cells reach more than
  /// this beyond the typical cross-section (the median extents over all slices) is left out of the fit, with its
  /// neighbours, when enough clean slices remain: a wall joining at a corner or a T, or a speck, would pull the
  /// line there [cells], [0, 10].
  double slice_tolerance_cells = 0.75;
  double max_gap_m = 0.25;    // skeleton cells farther apart along a line start a new segment [m], > 0
  double min_length_m = 0.3;  // shorter segments are dropped [m], >= 0
  std::size_t min_cells = 6;  // segments with fewer skeleton cells are dropped, >= 2
  int refine_iterations = 8;  // at most this many rounds of fit → re-collect along the fitted line, [1, 100]
  /// A laser-built grid's occupied band reaches 1–3 cells behind the surface that returned the beams, so a band
  /// with free space on one side only gives its line on that edge (the surface), not through its centre. false:
  /// every line through its band's centre (a drawn map, whose walls are painted about their axes).
  bool place_on_surface = true;
};

/// @throw std::invalid_argument for a field outside the ranges documented in GridLineOptions or HoughOptions.
void validate(const GridLineOptions& options);

/// Position standard deviation [m] of a cell centre in the line fit, the seed paper's eq. 3:
/// σx = σy = Δ_raster / P_occ.
/// @throw std::invalid_argument for a resolution that is not finite and > 0, or p_occupied not in (0, 1].
double grid_cell_sigma_m(double resolution_m, double p_occupied);

/// Converts a raster map into line segments (the logical sensor of the seed paper §3, "conversion of the raster
/// map into vector form"), in the raster's world frame:
///  1. threshold at p_occupied, fill_small_holes, then zhang_suen_thinning;
///  2. Hough transform of the skeleton with non-maximum suppression (hough_peaks); peaks are taken strongest
///     first, and a peak with a near-equal rival in its window is settled on the grey grid;
///  3. the skeleton cells near the peak's line are split at gaps longer than max_gap_m into runs; each run is
///     refined: the occupied cells across it (fit band, corner slices left out) are fitted by weighted total
///     least squares (fit_line) with σ from eq. 3 per cell, and the run is re-collected along the fitted line
///     (so a long wall is followed beyond the Hough bin's reach), until neither the run nor the line moves;
///  4. a run with at least min_cells skeleton cells and min_length_m becomes a segment; its skeleton cells (all
///     within the fit band over its extent) are claimed, so each skeleton cell serves at most one segment, and
///     their votes leave the accumulator before the next peak is taken (peaks are re-scored lazily);
///  5. with place_on_surface, a segment whose band borders free space on one side only (most cuts across it, one
///     per cell) is moved parallel to that side's edge, the median centre of the first occupied cell there (within
///     half a cell of the surface the laser saw), and its ends in to the outermost cuts that show that edge.
/// Each segment's line carries the fit's covariance C_L over (ρ [m], φ [rad]), for a moved one with the offset σ
/// at its middle floored at cell/√12 (the edge is known to a cell); its extent spans the fitted cells' centres
/// plus half a cell at each end (a moved one's: its cuts). Segments come in the order found (strongest line first).
/// @throw std::invalid_argument for an invalid raster or options.
std::vector<LineSegment> extract_grid_lines(const ProbabilityRaster& raster, const GridLineOptions& options);

}  // namespace wm::fusion
