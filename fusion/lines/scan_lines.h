#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "fusion/geometry/line.h"
#include "fusion/geometry/pose2d.h"

namespace wm::fusion {

/// Settings of the scan line extractor (split-and-merge, docs/fusion.md §2 for the fit).
struct ScanLineOptions {
  std::size_t min_points = 6;  // fewer points in a piece as split: no segment (its fit may keep 4 after trimming)
  double min_length_m = 0.3;   // shorter: no segment
  double max_gap_m = 0.25;     // consecutive points farther apart start a new segment, unless far_gap_lambda_rad...
  /// ...says the gap is the spacing of a far surface: a gap over max_gap_m does not cut when both returns lie within
  /// far_gap_max_range_m and the gap is within the adaptive distance below at incidence far_gap_lambda_rad [rad]
  /// (0: max_gap_m always cuts). Far walls seen from 10–20 m by a 0.5° laser have returns 0.2–0.5 m apart: the truth
  /// benchmark's recall rose from 0.764 to 0.861 (Barcelona) and 0.894 to 0.903 (GDC1) with precision kept; over the
  /// 13 CARMEN logs recall rose by up to 0.040 (fhw) and the grid-backed precision fell by 0.010 at most (fhw). Beyond
  /// 20 m the 1° logs' sparse returns are outdoor clutter: with no range limit freiburg-campus fell from 0.943 to
  /// 0.773 and orebro from 0.974 to 0.894.
  double far_gap_lambda_rad = 0.2618;  // 15°
  double far_gap_max_range_m = 20.0;
  /// A far gap is never wider than this, so a doorway (0.8 m or more) always cuts: a 1° laser's spacing at 15° is
  /// 1.4 m from 20 m. On the CARMEN logs grid-backed precision rose by up to 0.003 (intel, fhw, freiburg-101) and
  /// fell nowhere; the truth benchmark was unchanged. (An incidence of 10° instead of 15° raised the truth
  /// benchmark's recall on Barcelona from 0.862 to 0.889, a 5 m wall seen only at grazing angles, but cost the 1°
  /// CARMEN logs up to 0.009 of precision: edmonton 0.982 → 0.973.)
  double far_gap_max_m = 0.75;
  /// Angle between neighbouring beams [rad] (0: not known). When it is known, the far-gap spacing above is allowed
  /// only between returns of beams at most max_missing_beams apart: the beams between two returns 9° apart would
  /// have hit a surface joining them, and returned nothing (an opening: Barcelona's 2.3 m gap between a wall's end
  /// and a far wall 14 m away had become one 5 m line along the wall).
  double bearing_step_rad = 0.0;
  std::size_t max_missing_beams = 2;
  /// Adaptive breakpoint detector (Borges & Aldon, J. Intell. Robot. Syst. 39, 2004): consecutive points
  /// p_{n−1}, p_n also start a new segment when ‖p_n − p_{n−1}‖ > r_{n−1}·sin Δφ / sin(λ − Δφ) + 3σ_r, Δφ their
  /// bearing difference, σ_r the range noise. That distance is how far apart two returns from one surface seen at
  /// incidence λ can be, so a depth step (a door frame, a pilaster) seen at a steeper angle is cut and no piece
  /// spans it; a surface seen flatter than λ falls apart into points, too few for a line. λ [rad], in (0, π/2);
  /// a Δφ of λ or more is always a breakpoint.
  double breakpoint_lambda_rad = 0.1745;  // 10°
  bool adaptive_breakpoints = true;       // false: only max_gap_m cuts
  /// A jump past the adaptive distance is a breakpoint only when it is also this many times the spacing of the
  /// points on either side of it (the larger): at a depth step one jump stands out among small spacings, while a
  /// wall seen at a grazing angle has spacings that grow smoothly from point to point and stays one run. Without
  /// this, freiburg-079 (1° beams) lost 0.054 of recall to corridor walls seen at under 9°; with 3 it loses 0.012
  /// (2: 0.019, 4: 0.010), and the truth benchmark's precision is the same from 2 to 4. 0: no such test.
  double breakpoint_isolation = 3.0;
  double split_distance_m = 0.03;  // split where a point is farther than max(this, 3σ) from the chord
  /// A piece that passes the split's test is also split where two parallel lines (one direction, two offsets) fit
  /// it with offsets more than twice split_distance_m (and 4σ of their difference) apart: a door frame or pilaster
  /// 6–10 cm proud of its wall, seen from the side of its step, gives no range jump, and a line through both faces
  /// lies within 4 cm of every return, tilted toward the frame. On the truth benchmark's AHG2 (frames drawn 8–15 cm
  /// proud) precision rose 0.976 → 0.981 (low pose noise) and 0.959 → 0.964 (high); on the CARMEN logs recall fell
  /// by 0.007 at most (edmonton, acapulco). false: only the split's test.
  bool split_steps = true;
  /// A piece that passes both tests is also split where two lines meeting at a point fit it with directions more
  /// than 4σ apart and the shorter side's end more than split_distance_m off the longer side's line: the facets of
  /// a curved wall 6–9° apart, or a shallow corner, seen as one piece give a line through the bend that no return
  /// lies far from, which the map then stretches past the corner. false: no such test.
  bool split_bends = true;
  double merge_chi2 = 5.991;    // χ², 2 dof (95 %): adjacent segments whose lines agree are merged
  double sigma_range_m = 0.01;  // range noise per reading, plus sigma_range_relative · range
  double sigma_range_relative = 0.0;
  double sigma_bearing_rad = 0.0005;  // bearing noise per beam (angular jitter of the scanner)
  /// Scale a fit's covariance by its reduced χ² (Σ residual²/σ² over n − 2) when that exceeds 1, so a segment whose
  /// points scatter more than the noise model says is not trusted as if they did not.
  bool scale_by_residuals = true;
};

/// One range reading: its range [m] and bearing in the sensor frame [rad].
struct RangeReading {
  double range_m;
  double bearing_rad;
};

/// Extracts line segments from one ordered scan (readings in beam order; invalid ones already removed).
/// Points are cut into runs at gaps and breakpoints (max_gap_m, the adaptive breakpoint detector), each run is split
/// recursively at the farthest point from the chord (iterative end-point fit), trimmed of up to four end points that
/// lie off the line of the others (the corner a split shares, a mixed return at a step), fitted by weighted total
/// least squares with per-point covariance from range and bearing noise, and neighbouring pieces of one run whose
/// lines pass a χ² test are merged and refitted when every point between and under them lies on the merged line
/// (so a wall is never joined across a pilaster or a recess whose own piece was too short to keep). The segments are
/// returned in the world frame: `sensor_pose` places the sensor, `pose_cov` (3×3 over x, y, θ) is propagated into each
/// line's covariance. @throw std::invalid_argument for non-finite readings or pose, or bad options.
std::vector<LineSegment> extract_scan_lines(const std::vector<RangeReading>& readings, const Pose2D& sensor_pose,
                                            const Eigen::Matrix3d& pose_cov, const ScanLineOptions& options);

}  // namespace wm::fusion
