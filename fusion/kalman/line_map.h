#pragma once

#include <cstddef>
#include <optional>
#include <span>

#include "fusion/geometry/line.h"

namespace wm::fusion {

/// When an observed segment counts as the same element as a mapped one (docs/fusion.md §4 "Gating in the segment's
/// frame"). The test is made where the two segments overlap, in the element's frame: the direction difference and
/// the perpendicular offsets at both ends of the overlap, each against `gate_sigmas` standard deviations of the
/// difference (from both covariances) but never less than a floor, plus the gap along the line. A χ² gate on (ρ, φ)
/// would multiply a small direction error by the distance to the origin (0.5° at 20 m is 17 cm) and, against an
/// over-confident element, reject every new view of its own wall.
struct MatchOptions {
  double gate_sigmas = 3.0;      // an offset or direction difference within this many σ passes, > 0
  double min_offset_m = 0.03;    // tolerance floor across the line [m]: no element is known better than this
  double min_angle_rad = 0.035;  // tolerance floor on the direction (2°) [rad]
  double max_gap_m = 0.10;       // largest gap between the extents (projected on the element's line) still matched [m]
  /// Also allow the direction to differ by atan(min_offset_m / observed length): a short view's direction is
  /// only known to about that, a long one's much better, so a long view that turns away is another wall.
  bool angle_floor_from_length = true;
};

/// Mahalanobis distance² between two lines: Δᵀ(Ca+Cb)⁻¹Δ, with Δφ wrapped and the better of b's two
/// equivalent representations (ρ,φ) / (−ρ,φ+π) (with cov sign flip) used. Inputs need not be normalized.
/// It is the normalised innovation reported with a match (calibration counts it against χ²(2)), not the gate.
/// @throw std::invalid_argument if Ca + Cb is not positive definite (or not finite).
double mahalanobis_squared(const LineFeature& a, const LineFeature& b);

/// Gap [m] between the extents of `element` and `observed` projected onto element's line; 0 when they overlap
/// or touch. The gap is what keeps collinear walls either side of a doorway apart.
double extent_gap_m(const LineSegment& element, const LineSegment& observed);

/// Variance [m²] of a line's perpendicular position at coordinate t along it: C_ρρ − 2t·C_ρφ + t²·C_φφ.
double offset_variance_at(const LineFeature& line, double t_m);

/// The segment-frame test of `observed` against `element` in numbers.
struct SegmentGate {
  double angle_rad = 0;         // |direction difference|, lines undirected, in [0, π/2]
  double angle_limit_rad = 0;   // what passes
  double offset_m[2] = {0, 0};  // |observed line − element line| at both ends of the overlap, across the element
  double offset_limit_m[2] = {0, 0};
  double gap_m = 0;
  bool passes = false;
  /// Σ (difference / limit)² over the angle and both offsets: ranks candidates that pass (smaller is closer).
  double cost = 0;
};
/// @throw std::invalid_argument for non-finite input.
SegmentGate segment_gate(const LineSegment& element, const LineSegment& observed, const MatchOptions& options);

struct MatchResult {
  std::size_t index;      // into the candidates
  double mahalanobis_sq;  // normalised innovation d² of the match (reported, not gated)
  double cost;            // SegmentGate::cost
};

/// The match of `observed` against one element, or nullopt when the segment gate rejects it.
/// @throw std::invalid_argument as mahalanobis_squared.
std::optional<MatchResult> match_segment(const LineSegment& element, const LineSegment& observed,
                                         const MatchOptions& options);

/// Passing candidate with the smallest gate cost, ties broken by the lower index; nullopt if none.
/// @throw std::invalid_argument as mahalanobis_squared.
std::optional<MatchResult> best_match(std::span<const LineSegment> candidates, const LineSegment& observed,
                                      const MatchOptions& options);

/// How far fusion may shrink an element's uncertainty. Lines of one wall seen from one trajectory share the
/// pose error, so fusing them as independent measurements would shrink the covariance far below the truth; the
/// floor, in the midpoint form (σ across the line at the segment's middle, σ of the direction), is what the
/// poses are known to, not what the fits say.
struct FusionOptions {
  double min_offset_sigma_m = 0.0;
  double min_angle_sigma_rad = 0.0;
};

/// Information-form fusion (Kalman update with H = I, docs/fusion.md §4) of observed into element:
/// P = (Pa⁻¹+Pb⁻¹)⁻¹, L = P(Pa⁻¹La + Pb⁻¹Lb) with observed expressed in element's representation (the closer of
/// its two representations, φ unwrapped next to element's), result normalized; extent = union of the four
/// endpoints projected onto the fused line.
/// @throw std::invalid_argument for singular (not positive definite) or non-finite covariances.
LineSegment fuse(const LineSegment& element, const LineSegment& observed);
/// fuse(), then the covariance raised to the floor of `options` where it went below (in the midpoint form).
LineSegment fuse(const LineSegment& element, const LineSegment& observed, const FusionOptions& options);
/// The segment with its covariance raised to the floor of `floor` where it is below, in the midpoint form
/// M = A C Aᵀ, A = [[1, −t_mid], [0, 1]] (t_mid the middle of the extent): M_oo ≥ σ_offset², M_φφ ≥ σ_angle².
LineSegment with_covariance_floor(LineSegment segment, const FusionOptions& floor);

}  // namespace wm::fusion
