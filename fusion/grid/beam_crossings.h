#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "fusion/grid/scan.h"

namespace wm::fusion {

/// What the beams of laser scans did at one line segment, in bins of equal length along it (from p0): how many
/// passed through it (their return, or their free space without one, lies beyond the segment by more than the
/// margin) and how many ended on it (returned within the margin of it). Evidence for a drawn wall that the grid
/// alone does not give: the grid clamps, so it cannot say how many beams saw a place.
struct SegmentBeams {
  Eigen::Vector2d p0 = Eigen::Vector2d::Zero(), p1 = Eigen::Vector2d::Zero();  // [m]
  std::vector<std::uint32_t> through, ended;  // one count per bin, saturating at 2^32 − 1
};

struct BeamCrossingOptions {
  double bin_m = 0.10;  // bin length along a segment [m], > 0
  /// A return within this of the segment, measured across it, ended on it; beyond it by more, it passed [m], > 0.
  /// Widened per beam by two σ of where the pose and the reading put the return across the segment.
  double margin_m = 0.10;
  /// Beams closer than this to running along the segment are not counted: at a grazing angle a beam's range error
  /// moves its crossing point far along the segment [rad], in [0, π/2).
  double min_incidence_rad = 0.17;
};

/// The bins a segment of this length gets: ceil(length / bin_m), at least 1.
std::size_t beam_bins(double length_m, const BeamCrossingOptions& options);

/// Adds the beams of `scan` to the counts of `segments` (each sized by beam_bins). A beam is walked up to
/// `reach_m` (the grid's usable range): a return beyond it, or no return, means free space up to reach_m.
/// `pose_cov` (x, y, θ) is the sensor pose's covariance: a beam's margin widens with it. Cost: for each segment,
/// only the beams whose bearing lies between its ends'.
/// @throw std::invalid_argument for bad options, a non-finite reach or covariance, a scan validate() refuses, or a
///        segment whose bins do not match its length.
void count_beam_crossings(const LaserScan& scan, double reach_m, const BeamCrossingOptions& options,
                          std::vector<SegmentBeams>& segments,
                          const Eigen::Matrix3d& pose_cov = Eigen::Matrix3d::Zero());

}  // namespace wm::fusion
