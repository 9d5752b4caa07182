#include "fusion/lines/line_continuation.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

namespace wm::fusion {
namespace {

void validate(const LineContinuationOptions& o) {
  const bool ok = o.min_points >= 2 && o.min_length_m >= 0 && o.offset_sigmas > 0 && o.min_offset_m > 0 &&
                  o.max_gap_m > 0 && o.spacing_factor >= 0 && o.max_spacing_m >= o.max_gap_m &&
                  o.bearing_step_rad >= 0 && o.max_incidence_rad > 0 && o.max_incidence_rad <= 1.5708 &&
                  o.max_range_m > 0 && o.sigma_range_m > 0 && o.sigma_range_relative >= 0 && o.sigma_bearing_rad >= 0 &&
                  std::isfinite(o.max_spacing_m) && std::isfinite(o.max_range_m);
  if (!ok) throw std::invalid_argument("continue_line: options out of range");
}

// The index runs of `beams` (in increasing bearing order over less than a full turn) whose bearing lies on the arc
// from `from` turning counter-clockwise by `sweep` in [0, 2π) [rad]: one run, or two where the arc wraps past the
// first beam's bearing.
std::vector<std::pair<std::size_t, std::size_t>> beams_on_arc(std::span<const ContinuationBeam> beams, double from,
                                                              double sweep) {
  std::vector<std::pair<std::size_t, std::size_t>> runs;
  if (beams.empty()) return runs;
  constexpr double kTurn = 2 * std::numbers::pi;
  const double first = beams.front().bearing_rad;
  const double start = first + std::fmod(std::fmod(from - first, kTurn) + kTurn, kTurn);  // in [first, first + 2π)
  const auto index_of = [&](double bearing) {
    return static_cast<std::size_t>(
        std::lower_bound(beams.begin(), beams.end(), bearing,
                         [](const ContinuationBeam& b, double value) { return b.bearing_rad < value; }) -
        beams.begin());
  };
  const double end = start + sweep;
  runs.emplace_back(index_of(start), index_of(std::min(end, first + kTurn) + 1e-12));
  if (end > first + kTurn) runs.emplace_back(0, index_of(end - kTurn + 1e-12));
  return runs;
}

}  // namespace

std::optional<LineSegment> continue_line(std::span<const ContinuationBeam> beams, const LineSegment& known,
                                         bool beyond_t1, const LineContinuationOptions& options,
                                         const ForeignReturn& foreign) {
  validate(options);
  for (const auto& beam : beams)
    if (!std::isfinite(beam.bearing_rad)) throw std::invalid_argument("continue_line: a bearing is not finite");
  // A segment's line is normalized (ρ ≥ 0): its normal points from the sensor toward it, so a beam meets it where
  // n·u > 0.
  const LineFeature& line = known.line;
  const double t_end = beyond_t1 ? known.t1_m : known.t0_m;
  const double outward = beyond_t1 ? 1.0 : -1.0;
  const double max_incidence = std::sin(options.max_incidence_rad);
  // The line runs through the sensor (no beam meets it), or lies too far for any beam within range to graze it.
  if (!(line.rho_m > 1e-3) || line.rho_m > options.max_range_m * max_incidence) return std::nullopt;
  const Eigen::Vector2d n = line.normal(), d = line.direction();

  // The stretch past the end within range subtends an arc from the end's bearing to the bearing of its farthest
  // point (each beam meets a line once, so the arc is under half a turn).
  const Eigen::Vector2d end_point = line.rho_m * n + t_end * d, away = outward * d;
  const double along = end_point.dot(away),
               reach_sq = along * along - end_point.squaredNorm() + options.max_range_m * options.max_range_m;
  if (end_point.norm() >= options.max_range_m || reach_sq <= 0) return std::nullopt;
  const Eigen::Vector2d far_point = end_point + (-along + std::sqrt(reach_sq)) * away;
  const double end_bearing = std::atan2(end_point.y(), end_point.x());
  const double turn = std::remainder(std::atan2(far_point.y(), far_point.x()) - end_bearing, 2 * std::numbers::pi);
  // Walk the arc from the end outward: along it, the beams meet the line ever farther past the end.
  const auto runs = beams_on_arc(beams, turn >= 0 ? end_bearing : end_bearing + turn, std::abs(turn));
  std::vector<std::size_t> order;
  for (const auto& [first, last] : runs)
    for (std::size_t i = first; i < last; ++i) order.push_back(i);
  if (turn < 0) std::reverse(order.begin(), order.end());

  std::size_t taken = 0;
  double last_m = 0;                   // the end itself, then each return on the line
  double first_m = 0, farthest_m = 0;  // the returns taken
  for (const auto i : order) {
    const auto& beam = beams[i];
    const Eigen::Vector2d& u = beam.direction;
    if (!u.allFinite()) throw std::invalid_argument("continue_line: a beam direction is not finite");
    const double incidence = n.dot(u);
    if (incidence <= 1e-6) continue;
    const double line_range = line.rho_m / incidence;
    if (line_range > options.max_range_m) break;
    const double past = outward * (line_range * d.dot(u) - t_end);
    if (past <= 0) continue;
    const double spacing = options.bearing_step_rad * line_range / incidence;
    const double allowed =
        std::min(options.max_spacing_m, std::max(options.max_gap_m, options.spacing_factor * spacing));
    if (past - last_m > allowed) break;  // nothing on the line over a gap too wide to bridge
    const double r = beam.range_m;
    if (!std::isfinite(r)) break;  // no return: the beam went on through where the wall would be
    // Across the line, a return is off by its range error times the incidence and its bearing error's lever.
    const double sigma_r = options.sigma_range_m + options.sigma_range_relative * r;
    const double sigma_across = std::hypot(sigma_r * incidence, r * options.sigma_bearing_rad * std::abs(d.dot(u)));
    const double tolerance = std::max(options.min_offset_m, options.offset_sigmas * sigma_across);
    const double in_front = (line_range - r) * incidence;  // > 0: the return lies between sensor and line
    if (in_front > tolerance) break;                       // something nearer hides the line
    if (in_front < -tolerance) break;                      // the beam went through where the wall would be
    if (foreign && foreign(i)) break;                      // a neighbour's line has this return: this one ends
    if (beam.claimed) {  // a line of the scan's own has this return: the wall goes on, but not as new evidence
      last_m = past;
      continue;
    }
    if (incidence > max_incidence) break;  // not a grazing view: the extractor's to make a line of, or nobody's
    if (++taken == 1) first_m = past;
    last_m = farthest_m = past;
  }
  // The returns themselves must spread along the line: a few returns bunched where a crossing wall meets it (a
  // corner) lie on the line too, but say nothing about where it goes.
  if (taken < options.min_points || farthest_m - first_m < options.min_length_m) return std::nullopt;
  LineSegment segment = known;
  if (beyond_t1) {
    segment.t0_m = known.t1_m;
    segment.t1_m = known.t1_m + farthest_m;
  } else {
    segment.t1_m = known.t0_m;
    segment.t0_m = known.t0_m - farthest_m;
  }
  return segment;
}

}  // namespace wm::fusion
