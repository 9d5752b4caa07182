#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <functional>
#include <optional>
#include <span>

#include "fusion/geometry/line.h"

namespace wm::fusion {

/// One beam of a scan, in the sensor's frame, as continue_line reads it.
struct ContinuationBeam {
  double bearing_rad = 0;
  Eigen::Vector2d direction = Eigen::Vector2d::UnitX();  // (cos, sin) of the bearing
  double range_m = 0;    // +inf: nothing returned within the sensor's range (the beam went on past any line)
  bool claimed = false;  // its return lies on a segment the scan-line extractor made of this scan

  static ContinuationBeam at(double bearing_rad, double range_m, bool claimed = false) {
    return {bearing_rad, {std::cos(bearing_rad), std::sin(bearing_rad)}, range_m, claimed};
  }
};

/// Whether the return of beams[i] lies on another line of the map (a neighbour's facet, a crossing wall): the
/// continuation stops there. Asked only of the few returns a continuation reaches.
using ForeignReturn = std::function<bool(std::size_t)>;

/// Settings of continue_line.
struct LineContinuationOptions {
  std::size_t min_points = 3;  // returns on the line past its end, at least
  double min_length_m = 0.3;   // the returns taken spread at least this far along the line [m]
  /// A return lies on the line within max(min_offset_m, offset_sigmas · its own σ across the line) [m].
  double offset_sigmas = 4.0;
  double min_offset_m = 0.02;
  /// Consecutive returns on the line (and the end and the first of them) may lie max_gap_m apart, or up to
  /// spacing_factor times the spacing one beam step gives on the line there (r·Δβ / sin of the incidence), but
  /// never more than max_spacing_m [m]: a grazing wall's returns spread out smoothly, a doorway's edge does not.
  double max_gap_m = 0.25;
  double spacing_factor = 2.5;
  double max_spacing_m = 0.75;
  /// Only a return whose beam meets the line at under this angle is taken [rad]: steeper, the returns are dense
  /// enough for the extractor, and one it left alone (too few for a line, past a shallow bend) is no continuation.
  double max_incidence_rad = 0.2618;  // 15°
  double bearing_step_rad = 0.0;      // between neighbouring beams; 0: only max_gap_m
  double max_range_m = 20.0;          // beams whose crossing with the line lies farther do not count [m]
  double sigma_range_m = 0.01;        // range noise per reading, plus sigma_range_relative · range
  double sigma_range_relative = 0.0;
  double sigma_bearing_rad = 0.0005;
};

/// How far a known line runs past one of its ends, as a scan's sparse returns show: a wall seen at a grazing angle
/// from afar has returns 0.5–1 m apart, too few and too far apart for the scan-line extractor, yet each lies on the
/// wall's line to a centimetre. `known` is in the sensor's frame (sensor at the origin); `beyond_t1` picks the end
/// (t1, else t0). Beams crossing the line past that end are taken outward, nearest first; the continuation goes on
/// while each is a return on the line (within the offset tolerance), at a grazing angle (max_incidence_rad),
/// following the last within the gap allowance. It stops at a gap too wide, at a steeper return, at a beam that
/// returned in front of the line (something hides the wall), behind it or not at all (the beam went through where the
/// wall would be), and at a return on another line of the map (a neighbouring facet or a crossing wall: that line's). A
/// return the extractor claimed is stepped over: it continues the wall but is that line's evidence, not the
/// continuation's. Result: `known`'s line from the end to the farthest return taken (a continuation says how far the
/// line runs, not where it lies); nullopt when fewer than min_points were taken or they spread over less than
/// min_length_m along the line. `beams` are in increasing bearing order over less than a full turn (a scan's order):
/// only those on the arc the line's stretch past the end subtends are looked at. A line farther from the sensor than
/// max_range_m · sin(max_incidence_rad) is never seen at a grazing angle within range: nullopt at once.
/// @throw std::invalid_argument for a non-finite bearing or direction, or options out of range.
std::optional<LineSegment> continue_line(std::span<const ContinuationBeam> beams, const LineSegment& known,
                                         bool beyond_t1, const LineContinuationOptions& options = {},
                                         const ForeignReturn& foreign = {});

}  // namespace wm::fusion
