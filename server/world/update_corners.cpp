// Elements that run past a shallow corner onto the next facet's element are cut back to the corner.
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <string>
#include <utility>

#include "server/world/update_internal.h"

namespace wm::world::update_internal {
namespace {

// Less than this past the corner is left: the crossing itself moves by that much as the two lines take in views,
// and a cut per scan of a few millimetres would fill the decision log.
constexpr double kShortestCornerCutM = 0.02;

}  // namespace

std::optional<CornerCut> cut_past_corner(const fusion::LineSegment& a, const fusion::LineSegment& b,
                                         const WorldOptions& options) {
  const double angle = std::abs(std::remainder(a.line.phi_rad - b.line.phi_rad, std::numbers::pi));
  if (angle < options.corner_min_angle_rad || angle > options.corner_max_angle_rad) return std::nullopt;
  // Where the two lines cross: n_a·x = ρ_a, n_b·x = ρ_b (not parallel: the angle is at least the minimum).
  Eigen::Matrix2d normals;
  normals << a.line.normal().transpose(), b.line.normal().transpose();
  const Eigen::Vector2d corner = normals.inverse() * Eigen::Vector2d(a.line.rho_m, b.line.rho_m);
  const double ta = a.line.coordinate_along(corner);
  if (ta <= a.t0_m || ta >= a.t1_m) return std::nullopt;  // a does not run through the corner
  // a's shorter side past the corner is the part that may lie along b.
  const bool past_t1 = a.t1_m - ta < ta - a.t0_m;
  const double overshoot = past_t1 ? a.t1_m - ta : ta - a.t0_m;
  const Eigen::Vector2d end = past_t1 ? a.p1() : a.p0();
  if (overshoot < kShortestCornerCutM || overshoot * std::sin(angle) > options.corner_overshoot_offset_m)
    return std::nullopt;
  // b runs on from the corner the way a's overshoot goes, further than back, and covers it.
  const double tb = b.line.coordinate_along(corner), tb_end = b.line.coordinate_along(end);
  const double gap = options.match.max_gap_m;
  if (tb < b.t0_m - gap || tb > b.t1_m + gap || tb_end < b.t0_m - gap || tb_end > b.t1_m + gap) return std::nullopt;
  const double b_on_that_side = tb_end > tb ? b.t1_m - tb : tb - b.t0_m;
  const double b_on_the_other = tb_end > tb ? tb - b.t0_m : b.t1_m - tb;
  if (b_on_that_side < overshoot || b_on_that_side <= b_on_the_other) return std::nullopt;
  fusion::LineSegment kept = a;
  (past_t1 ? kept.t1_m : kept.t0_m) = ta;
  return CornerCut{kept, corner, overshoot, angle};
}

fusion::LineSegment stop_at_corners(const WorldState& state, std::int64_t number, const std::pair<double, double>& kept,
                                    fusion::LineSegment grown, const WorldOptions& options) {
  for (const auto other : state.elements.near(Box::of(grown, options.match.max_gap_m))) {
    if (other == number) continue;
    if (const auto c = cut_past_corner(grown, state.elements.at(other).segment, options)) {
      grown.t0_m = std::min(kept.first, std::max(grown.t0_m, c->kept.t0_m));
      grown.t1_m = std::max(kept.second, std::min(grown.t1_m, c->kept.t1_m));
    }
  }
  return grown;
}

void cut_at_corners(UpdateResult& result, std::int64_t number, const Observation& observation,
                    std::int64_t observation_seq, const WorldOptions& options) {
  WorldState& state = result.state;
  // No at_unix_s: a neighbour cut here was not seen by this observation, and the grown element's time is already set.
  const TrimSource source{observation_seq, observation.observer, "element", observation.sensor, std::nullopt};
  const auto cut_if_past = [&](std::int64_t from, std::int64_t along) {
    const Element& a = state.elements.at(from);
    const Element& b = state.elements.at(along);
    if (a.origin == "client" || !faces_agree(a.facing_rad, b.facing_rad)) return;
    const auto c = cut_past_corner(a.segment, b.segment, options);
    if (!c) return;
    const std::string along_id = b.id();
    char text[256];
    std::snprintf(text, sizeof text,
                  "element %s ran %.3f m past its corner with %s at (%.3f, %.3f) (lines %.1f deg apart): cut at the "
                  "corner",
                  a.id().c_str(), c->overshoot_m, along_id.c_str(), c->corner.x(), c->corner.y(),
                  c->angle_rad * 180.0 / std::numbers::pi);
    trim_element(result, from, c->kept, "corner_cut", text, source).matched_element = along_id;
  };
  const Box near = Box::of(state.elements.at(number).segment, options.match.max_gap_m);
  for (const auto other : state.elements.near(near)) {
    if (other == number || !state.elements.contains(other)) continue;
    if (!Box::of(state.elements.at(other).segment).overlaps(near)) continue;
    cut_if_past(other, number);
    cut_if_past(number, other);
  }
}

}  // namespace wm::world::update_internal
