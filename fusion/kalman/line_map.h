#pragma once

#include <cstddef>
#include <optional>
#include <span>

#include "fusion/geometry/line.h"

namespace wm::fusion {

/// When an observed segment counts as the same element as a mapped one (docs/fusion.md §4 "Gating", "Segment extent").
struct MatchOptions {
  double gate_chi2 = 5.991;  // χ²(2 dof) gate on (ρ, φ); 95 %
  double max_gap_m = 0.10;   // largest gap between the extents (projected on the element's line) still matched [m]
};

/// Mahalanobis distance² between two lines: Δᵀ(Ca+Cb)⁻¹Δ, with Δφ wrapped and the better of b's two
/// equivalent representations (ρ,φ) / (−ρ,φ+π) (with cov sign flip) used. Inputs need not be normalized.
/// @throw std::invalid_argument if Ca + Cb is not positive definite (or not finite).
double mahalanobis_squared(const LineFeature& a, const LineFeature& b);

/// Gap [m] between the extents of `element` and `observed` projected onto element's line; 0 when they overlap
/// or touch. The gap is what keeps collinear walls either side of a doorway apart, which the χ² gate cannot.
double extent_gap_m(const LineSegment& element, const LineSegment& observed);

/// d² when observed passes the gate against element (d² <= gate_chi2) AND extent_gap_m <= max_gap_m;
/// nullopt otherwise. @throw std::invalid_argument as mahalanobis_squared.
std::optional<double> match_distance(const LineSegment& element, const LineSegment& observed,
                                     const MatchOptions& options);

struct MatchResult {
  std::size_t index;      // into the candidates
  double mahalanobis_sq;  // d² of the match
};

/// Best (smallest d²) candidate passing match_distance, ties broken by the lower index; nullopt if none.
/// @throw std::invalid_argument as mahalanobis_squared.
std::optional<MatchResult> best_match(std::span<const LineSegment> candidates, const LineSegment& observed,
                                      const MatchOptions& options);

/// Information-form fusion (Kalman update with H = I, docs/fusion.md §4) of observed into element:
/// P = (Pa⁻¹+Pb⁻¹)⁻¹, L = P(Pa⁻¹La + Pb⁻¹Lb) with observed expressed in element's representation (the closer of
/// its two representations, φ unwrapped next to element's), result normalized; extent = union of the four
/// endpoints projected onto the fused line.
/// @throw std::invalid_argument for singular (not positive definite) or non-finite covariances.
LineSegment fuse(const LineSegment& element, const LineSegment& observed);

}  // namespace wm::fusion
