#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>

#include "fusion/geometry/line.h"

namespace wm::fusion {

/// Length-weighted moments of the observed segments an element was built from, each taken as mass spread evenly
/// along it, in the world frame. The Kalman state forgets where the data lay; these do not, so a merge that would
/// bend an element (a corridor wall bowed by pose drift, two walls meeting at a shallow angle) shows as mass far
/// from its best line, whatever the covariances say. Sums, so joining two elements adds their moments.
struct SegmentMoments {
  double weight = 0.0;                               // Σ length [m]
  Eigen::Vector2d first = Eigen::Vector2d::Zero();   // Σ length·centre [m²]
  Eigen::Matrix2d second = Eigen::Matrix2d::Zero();  // Σ length·(c·cᵀ + d·dᵀ/12), d = p1 − p0 [m³]

  /// The moments of one segment.
  static SegmentMoments of(const LineSegment& segment);
  SegmentMoments& operator+=(const SegmentMoments& other);
  friend SegmentMoments operator+(SegmentMoments a, const SegmentMoments& b) { return a += b; }

  /// RMS distance of the mass from its best-fitting line [m]: √ of the smaller eigenvalue of the scatter
  /// second/weight − mean·meanᵀ. 0 when empty.
  double rms_offset_m() const;

  /// RMS distance of the mass from `line` [m]: how far a short wall lies beside a long one's line, which the RMS of
  /// the two together (weighing each by its length) hardly shows. 0 when empty.
  double rms_offset_from_m(const LineFeature& line) const;

  /// The line that fits the mass best (total least squares: through its mean, along the scatter's major axis), as
  /// a segment that keeps `near`'s covariance, turns its normal to `near`'s side and spans `near`'s ends projected
  /// on it. nullopt when the moments are empty or have no major axis. Refitting an element this way after each
  /// fusion weighs every view by its length, in any order (Pfister, Roumeliotis & Burdick, ICRA 2003), so a run of
  /// short, tilted views of one end cannot turn a long wall the way a Kalman update with a covariance floor does.
  std::optional<LineSegment> refit(const LineSegment& near) const;

  /// As stored: weight, first (2), second (xx, xy, yy).
  std::array<double, 6> to_array() const;
  static SegmentMoments from_array(const std::array<double, 6>& values);
};

}  // namespace wm::fusion
