#pragma once

#include <cstdint>
#include <numbers>
#include <span>
#include <vector>

#include "fusion/grid_lines/raster.h"

namespace wm::fusion {

/// Settings of the (ρ, φ) Hough transform on a raster (seed paper §3, eq. 2: x cos φ + y sin φ − ρ = 0).
struct HoughOptions {
  double rho_step_cells = 1.0;                     // ρ bin [cells], [0.25, 16]
  double theta_step_rad = std::numbers::pi / 180;  // φ bin [rad], [1e-4, π/8]; rounded so that π/step is whole
  double min_votes = 6.0;                          // weaker peaks are ignored [pixels, or Σp when weighted], > 0
  /// Non-maximum suppression: of the peaks closer than nms_rho_m in ρ [m] and nms_theta_rad in φ [rad] (both),
  /// only the strongest is kept, so that the two faces of a wall or a ragged skeleton give one line. >= 0 each.
  double nms_rho_m = 0.15;
  double nms_theta_rad = 2.0 * std::numbers::pi / 180;
  /// A peak is ambiguous when another local maximum inside its suppression window has at least this fraction
  /// of its votes; such peaks are settled on the grey grid (the raster itself): the candidate whose strip holds
  /// the most occupancy mass wins. > 0; a value above 1 turns the fallback off.
  double ambiguous_ratio = 0.8;
  /// Cells with p >= this count in the grey-grid fallback, each with weight p, (0, 1].
  float grey_min_p = 0.5f;
};

/// @throw std::invalid_argument for a field outside the ranges documented in HoughOptions.
void validate(const HoughOptions& options);

/// How the pixels of the image vote.
enum class HoughWeighting {
  binary,     // one vote per pixel (the paper's transform on the skeleton)
  occupancy,  // the pixel's occupancy probability from the raster (the grey grid; unknown cells vote 0)
};

/// A line found by the transform, in the world frame: x cos φ + y sin φ = ρ, normalized (ρ >= 0, φ in (−π, π]).
struct HoughPeak {
  double rho_m = 0.0;
  double phi_rad = 0.0;
  double votes = 0.0;          // accumulator value of the peak's bin
  bool grey_resolved = false;  // the peak was ambiguous and settled on the grey grid
};

/// Hough transform of the nonzero pixels of `image` (row-major like raster.p, e.g. a skeleton from
/// zhang_suen_thinning) over the raster's geometry: an accumulator of rho_step × theta_step bins over φ ∈ [0, π),
/// its local maxima with at least min_votes, greedy non-maximum suppression in the (nms_rho_m, nms_theta_rad)
/// window (wrapping across φ = 0/π), and the grey-grid fallback for ambiguous peaks (HoughOptions).
/// Peaks come strongest first; their (ρ, φ) are bin centres, so accurate to half a bin.
/// @throw std::invalid_argument for an invalid raster or options, or an image whose size differs from the raster's.
std::vector<HoughPeak> hough_peaks(const ProbabilityRaster& raster, std::span<const std::uint8_t> image,
                                   const HoughOptions& options, HoughWeighting weighting = HoughWeighting::binary);

}  // namespace wm::fusion
