#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "fusion/grid_lines/hough.h"
#include "fusion/grid_lines/internal/raster_lines.h"
#include "fusion/grid_lines/raster.h"

// The (ρ, θ) accumulator behind hough_peaks() and extract_grid_lines(); not part of the public API.
namespace wm::fusion::internal {

/// An accumulator cell: angle bin t (θ = t·Δθ, 0 <= θ < π) and distance bin r (ρ = (r − R)·Δρ [cells]).
struct HoughBin {
  int t = 0;
  int r = 0;
  bool operator==(const HoughBin&) const = default;
};

/// (ρ, θ) Hough accumulator over a width × height raster in its centred cell frame (CellLine). Rows are angles
/// (θ-major), so voting one angle for all pixels touches one row. ρ bins are symmetric about ρ = 0 (bin R), which
/// makes the wrap θ → θ + π a mirror r → 2R − r. A pixel's bin is computed in 64-bit fixed point, so voting and
/// un-voting the same pixel always hit the same bins.
class HoughAccumulator {
 public:
  /// @throw std::invalid_argument for a raster size outside [1, kMaxRasterCells] or steps outside the ranges of
  ///        HoughOptions.
  HoughAccumulator(std::int64_t width, std::int64_t height, double rho_step_cells, double theta_step_rad);

  int theta_bins() const { return theta_bins_; }
  int rho_bins() const { return rho_bins_; }
  double rho_step_cells() const { return rho_step_; }
  double theta_step_rad() const { return theta_step_; }
  /// θ of bin t [rad] and ρ of bin r [cells].
  double theta_rad(int t) const;
  double rho_cells(int r) const;
  /// The line of a bin's centre.
  CellLine line(HoughBin b) const;
  /// The ρ bin of cell (x, y) at angle bin t.
  int rho_bin(int t, std::int64_t x, std::int64_t y) const;

  /// Every pixel (xs[i], ys[i]) votes once per angle, with weights[i] (all 1 when weights is empty).
  void vote(std::span<const std::int32_t> xs, std::span<const std::int32_t> ys, std::span<const float> weights);
  /// Every cell i of the row-major raster (cells = width·height) votes weight_of(i); cells weighing 0 or less (or
  /// NaN) are skipped.
  template <typename F>
  void vote_cells(std::size_t cells, F&& weight_of) {
    std::vector<std::int32_t> xs, ys;
    std::vector<float> weights;
    for (std::size_t i = 0; i < cells; ++i) {
      const float w = weight_of(i);
      if (!(w > 0.0f)) continue;
      xs.push_back(static_cast<std::int32_t>(static_cast<std::int64_t>(i) % width_));
      ys.push_back(static_cast<std::int32_t>(static_cast<std::int64_t>(i) / width_));
      weights.push_back(w);
    }
    vote(xs, ys, weights);
  }
  /// One pixel votes `weight` at every angle; a negative weight takes earlier votes back.
  void add(std::int64_t x, std::int64_t y, float weight);

  float at(HoughBin b) const { return votes_[index(b)]; }
  std::size_t index(HoughBin b) const {
    return static_cast<std::size_t>(b.t) * static_cast<std::size_t>(rho_bins_) + static_cast<std::size_t>(b.r);
  }
  std::size_t size() const { return votes_.size(); }
  /// Bin (t + dt, r + dr), with θ wrapped across 0/π (ρ mirrored); nullopt when ρ leaves the accumulator.
  std::optional<HoughBin> offset(HoughBin b, int dt, int dr) const;
  /// True when the bin has votes > 0 and no fewer than any of its 8 neighbours (plateaus give several).
  bool is_local_max(HoughBin b) const;

 private:
  std::int64_t width_;
  std::int64_t height_;
  double rho_step_;
  double theta_step_;
  int theta_bins_;
  int rho_bins_;
  int r_center_;
  std::vector<std::int64_t> cos_fixed_;  // cos θ_t / (2Δρ) · 2^kShift, per angle
  std::vector<std::int64_t> sin_fixed_;
  std::vector<float> votes_;
};

/// Half-sizes of the non-maximum-suppression window [bins].
struct NmsWindow {
  int dt = 0;
  int dr = 0;
};

/// The suppression window of HoughOptions in bins of `acc` for a raster of `resolution_m` cells: nms_rho_m and
/// nms_theta_rad divided by the bin sizes, rounded to the nearest whole bin.
NmsWindow nms_window(const HoughAccumulator& acc, double resolution_m, const HoughOptions& options);

/// Calls f(bin) for every bin of the window around `center` (center included), θ wrapped.
template <typename F>
void for_each_in_window(const HoughAccumulator& acc, HoughBin center, NmsWindow w, F&& f) {
  for (int dt = -w.dt; dt <= w.dt; ++dt) {
    for (int dr = -w.dr; dr <= w.dr; ++dr) {
      if (const auto b = acc.offset(center, dt, dr)) f(*b);
    }
  }
}

/// Local maxima with votes >= min_votes, strongest first (ties in bin order), then greedily thinned: a maximum
/// inside the window of a stronger kept one is dropped.
std::vector<HoughBin> nms_peaks(const HoughAccumulator& acc, float min_votes, NmsWindow window);

/// The grey-grid votes (the paper's fallback to the "grey" raster): for a bin, Σ p over the raster cells with
/// p >= grey_min_p whose ρ bin at the bin's angle is the bin's, i.e. the occupancy mass on the bin's strip. Built
/// once, on the first question, as a second accumulator with the same bins voted by those cells with weight p:
/// one pass over the occupied cells instead of a walk along the whole strip for every candidate.
class GreyVotes {
 public:
  GreyVotes(const HoughAccumulator& shape, const ProbabilityRaster& raster, float grey_min_p)
      : shape_(shape), raster_(raster), grey_min_p_(grey_min_p) {}
  double at(HoughBin b);

 private:
  const HoughAccumulator& shape_;
  const ProbabilityRaster& raster_;
  float grey_min_p_;
  std::optional<HoughAccumulator> votes_;
};

/// Settles an ambiguous peak. Rivals are the other local maxima in `window` around `peak` that are not
/// `excluded` (a byte per bin, may be empty) and have votes >= ratio · votes(peak). Without rivals the peak
/// stands; with rivals, the candidate (peak or rival) with the most grey votes wins (first on ties).
struct ResolvedPeak {
  HoughBin bin;
  bool ambiguous = false;
};
ResolvedPeak resolve_ambiguity(const HoughAccumulator& acc, HoughBin peak, NmsWindow window, double ratio,
                               std::span<const std::uint8_t> excluded, GreyVotes& grey);

}  // namespace wm::fusion::internal
