// Lines extracted from the grid: matched to the elements the scans built without moving them, and ends cut
// back to surfaces the grid saw.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <string_view>

#include "server/world/update_internal.h"

namespace wm::world::update_internal {
std::optional<std::int64_t> grid_line_on_element(const WorldState& state, const fusion::LineSegment& seen,
                                                 const GridLineMatchOptions& options) {
  std::optional<std::int64_t> best;
  double best_offset = std::numeric_limits<double>::infinity();
  for (const auto number : state.elements.near(Box::of(seen, options.on_element_offset_m))) {
    const Element& element = state.elements.at(number);
    if (made_by_grid(element)) continue;
    const fusion::LineSegment& e = element.segment;
    if (std::abs(std::remainder(seen.line.phi_rad - e.line.phi_rad, std::numbers::pi)) > options.on_element_angle_rad)
      continue;
    const double ta = e.line.coordinate_along(seen.p0()), tb = e.line.coordinate_along(seen.p1());
    if (std::min(std::max(ta, tb), e.t1_m) < std::max(std::min(ta, tb), e.t0_m)) continue;  // end to end
    const double offset =
        std::max(std::abs(e.line.signed_distance(seen.p0())), std::abs(e.line.signed_distance(seen.p1())));
    if (offset > options.on_element_offset_m || offset >= best_offset) continue;
    best = number;
    best_offset = offset;
  }
  return best;
}

std::optional<std::pair<double, double>> stretch_within(const fusion::LineFeature& line,
                                                        const fusion::LineSegment& segment, double offset_m) {
  double ta = line.coordinate_along(segment.p0()), tb = line.coordinate_along(segment.p1());
  double oa = line.signed_distance(segment.p0()), ob = line.signed_distance(segment.p1());
  if (ta > tb) {
    std::swap(ta, tb);
    std::swap(oa, ob);
  }
  // The offset runs linearly from oa at ta to ob at tb.
  double lo = ta, hi = tb;
  if (std::abs(ob - oa) > 1e-12) {
    const double slope = (ob - oa) / (tb - ta);
    const double u = (offset_m - oa) / slope, v = (-offset_m - oa) / slope;
    lo = std::max(lo, ta + std::min(u, v));
    hi = std::min(hi, ta + std::max(u, v));
  } else if (std::abs(oa) > offset_m) {
    return std::nullopt;
  }
  if (hi < lo) return std::nullopt;
  return std::pair{lo, hi};
}

void cut_at_grid_surfaces(UpdateResult& result, const std::set<std::int64_t>& surfaces, const Observation& observation,
                          std::int64_t observation_seq, const GridLineMatchOptions& options) {
  WorldState& state = result.state;
  for (const auto surface_number : surfaces) {
    const Element* surface = state.elements.find(surface_number);
    if (!surface) continue;
    const fusion::LineSegment wall = surface->segment;
    const std::string wall_id = surface->id();
    const Eigen::Vector2d nw = wall.line.normal();
    for (const auto number :
         state.elements.near(Box::of(wall, options.max_corner_cut_m + options.on_element_offset_m))) {
      if (number == surface_number) continue;
      const Element& element = state.elements.at(number);
      if (element.origin == "client") continue;
      const fusion::LineSegment& s = element.segment;
      if (std::abs(std::remainder(s.line.phi_rad - wall.line.phi_rad, std::numbers::pi)) <
          options.min_crossing_angle_rad)
        continue;
      // Where the lines cross: n_s·X = ρ_s and n_w·X = ρ_w.
      const Eigen::Vector2d ns = s.line.normal();
      const double det = ns.x() * nw.y() - ns.y() * nw.x();  // sin of the angle between them: not small here
      const Eigen::Vector2d crossing((s.line.rho_m * nw.y() - ns.y() * wall.line.rho_m) / det,
                                     (ns.x() * wall.line.rho_m - s.line.rho_m * nw.x()) / det);
      const double along_wall = wall.line.coordinate_along(crossing);
      if (along_wall < wall.t0_m - options.on_element_offset_m || along_wall > wall.t1_m + options.on_element_offset_m)
        continue;
      const double t = s.line.coordinate_along(crossing);
      const double past_hi = s.t1_m - t, past_lo = t - s.t0_m;
      fusion::LineSegment cut = s;
      if (past_hi >= options.min_corner_cut_m && past_hi <= options.max_corner_cut_m &&
          past_lo > options.max_corner_cut_m) {
        cut.t1_m = t;
      } else if (past_lo >= options.min_corner_cut_m && past_lo <= options.max_corner_cut_m &&
                 past_hi > options.max_corner_cut_m) {
        cut.t0_m = t;
      } else {
        continue;
      }
      char text[256];
      std::snprintf(text, sizeof text,
                    "element %s ran %.3f m past element %s, a surface the grid line extractor saw: cut from %.3f m "
                    "to %.3f m",
                    element.id().c_str(), s.length_m() - cut.length_m(), wall_id.c_str(), s.length_m(), cut.length_m());
      auto& record = trim_element(result, number, cut, "grid_crossing_trimmed", text,
                                  {observation_seq, observation.observer, observation.origin, observation.sensor,
                                   observation.received_at_unix_s});
      record.matched_element = wall_id;
    }
  }
}

}  // namespace wm::world::update_internal
