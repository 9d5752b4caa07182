#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <optional>
#include <vector>

#include "fusion/geometry/line.h"
#include "fusion/geometry/pose2d.h"

namespace wm::fusion {

/// A line of the map a scan may be aligned to, in the world frame with its covariance.
struct AlignmentReference {
  LineSegment segment;
  /// Direction [rad] of the normal pointing to the side the surface was seen from, when known: a scan sees a thin
  /// wall's face toward it, so a reference facing away is never its partner.
  std::optional<double> facing_rad;
};

struct ScanAlignmentOptions {
  /// Observed segments shorter than this do not vote [m]: a short piece's direction is poorly known.
  double min_segment_length_m = 0.5;
  /// A pair is a candidate while its two end distances pass a χ² test (2 dof) against their predicted spread (the
  /// pose's, the scan line's, the reference's): 13.8 is 99.9 %.
  double pair_chi2 = 13.82;
  /// A pair is ambiguous, and left out, while another reference also passes with a χ² under this many times the
  /// best's (two faces a few cm apart at a door frame, before the pose is known well enough to tell them apart).
  double ambiguity_ratio = 4.0;
  /// The observed segment must overlap the reference along it by this share of its own length.
  double min_overlap_share = 0.5;
  /// Two references whose lines lie within this many σ of the pair's own noise at both ends are one surface seen
  /// twice (a plan edge and an element on it, two pieces of one wall), not an ambiguity.
  double same_surface_sigmas = 2.0;
  /// At least this many pairs, or nothing moves. Parallel pairs are enough: a corridor's walls fix the pose across
  /// it and the heading, and the posted pose keeps its place along it (the prior).
  std::size_t min_pairs = 2;
  /// A pose posted with a σ above these is a guess, not an estimate to correct: the nearest lines would as likely be
  /// the wrong ones, and the search would reach across the whole map. It is left as posted [m], [rad].
  double max_posted_sigma_m = 0.5;
  double max_posted_sigma_rad = 0.1745;  // 10°
  /// Gauss-Newton passes (each re-pairs with the pose so far).
  int iterations = 4;
  /// The correction is refused when it lies farther than this from the posted pose under its covariance (χ², 3
  /// dof; 16.3 is 99.9 %): the pairs then fit a wrong hypothesis better than the robot's own estimate.
  double max_correction_chi2 = 16.27;
};

/// Where a scan's lines say its sensor is.
struct ScanAlignment {
  Pose2D pose;                                    // the corrected sensor pose (the posted one when not aligned)
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();  // its covariance over (x, y, θ)
  std::size_t pairs = 0;                          // scan lines paired with map lines in the last pass
  bool aligned = false;                           // false: too few or degenerate pairs, or a refused correction
};

/// Aligns one scan's lines to the map's lines: an iterated EKF update of the sensor pose (x, y, θ) from the
/// distances of each paired scan line's ends to its map line (the measurement model of Castellanos & Tardós's
/// SPmodel), with the posted pose and covariance as prior. `local` are the scan's segments in the sensor's own
/// frame, their covariance the sensor's noise only; `references` are the map's lines in the world frame. Each pass
/// pairs every long enough scan line with the one map line it passes the χ² gate against (ambiguous ones left
/// out), and the pose moves by the Gauss-Newton step of prior, map and pairs. A pose posted with zero covariance is
/// taken as exact, one with a σ over the options' limits as a guess: both are returned unchanged.
/// @throw std::invalid_argument for a non-finite pose or covariance, or one that is not symmetric positive
/// semi-definite.
ScanAlignment align_scan_lines(const std::vector<LineSegment>& local, const Pose2D& posted_pose,
                               const Eigen::Matrix3d& posted_cov, const std::vector<AlignmentReference>& references,
                               const ScanAlignmentOptions& options = {});

/// How far [m] the alignment looks for a map line around a point `range_m` from the sensor, for a pose with σ
/// `sigma_xy_m` in position and `sigma_theta_rad` in heading: 5 σ of what the pose moves that point by, plus 5 cm
/// (the pair gate, χ² 13.8 with 2 degrees of freedom, is 3.7 σ). Callers that gather the map lines use it too, so
/// that both look equally far.
double alignment_reach_m(double sigma_xy_m, double sigma_theta_rad, double range_m);

}  // namespace wm::fusion
