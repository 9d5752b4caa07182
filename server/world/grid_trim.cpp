#include "server/world/grid_trim.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "server/world/update_internal.h"

namespace wm::world {

GridTrimResult trim_to_grid(const WorldState& current, const Box& region, const GridProbe& probe,
                            std::int64_t observation_seq, const std::string& observer, const GridTrimOptions& options) {
  GridTrimResult trim_result{{current, {}, {}, {}, {}}, {}};
  UpdateResult& result = trim_result.update;
  WorldState& state = result.state;
  bool bumped = false;
  std::vector<GridEvidence> samples;
  for (const auto number : current.elements.near(region)) {
    const Element& element = current.elements.at(number);
    if (!region.crossed_by(element.segment)) continue;
    const fusion::LineSegment& segment = element.segment;
    const double length = segment.length_m();
    const auto steps = static_cast<std::size_t>(std::ceil(length / options.step_m));
    if (steps < 2) continue;
    const Eigen::Vector2d a = segment.p0(), b = segment.p1();
    samples.clear();
    for (std::size_t i = 0; i <= steps; ++i)
      samples.push_back(probe(a + (static_cast<double>(i) / static_cast<double>(steps)) * (b - a)));
    // From each end, up to the first sample that is not contrary; an end is cut only when that sample is backed
    // (an unknown one leaves the end as it is, and an element backed nowhere stays whole).
    std::size_t first = 0;
    while (first < steps && samples[first] == GridEvidence::contrary) ++first;
    if (samples[first] != GridEvidence::backed) first = 0;
    std::size_t last = steps;
    while (last > first && samples[last] == GridEvidence::contrary) --last;
    if (samples[last] != GridEvidence::backed) last = steps;
    const double dt = length / static_cast<double>(steps);
    const double t0 = segment.t0_m + static_cast<double>(first) * dt;
    const double t1 = segment.t0_m + static_cast<double>(last) * dt;
    const double cut = (t0 - segment.t0_m) + (segment.t1_m - t1);
    // Elements a client posted are not cut (a client may know of glass the laser sees through), nor cuts too small
    // to matter, nor elements whose backed part is too short to stand for them.
    const bool trims = element.origin != "client" && cut >= options.min_trim_m && t1 - t0 >= options.min_kept_m;
    // The rules hear of what stays: the kept extent when cut, else the whole element.
    const std::size_t from = trims ? first : 0, to = trims ? last : steps;
    std::size_t backed = 0, contrary = 0;
    for (std::size_t i = from; i <= to; ++i) {
      backed += samples[i] == GridEvidence::backed;
      contrary += samples[i] == GridEvidence::contrary;
    }
    const auto counted = static_cast<double>(to - from + 1);
    trim_result.checked.push_back(
        {number, static_cast<double>(backed) / counted, static_cast<double>(contrary) / counted});
    if (!trims) continue;

    if (!bumped) {
      state.version = current.version + 1;
      state.last_observation_seq = observation_seq;
      bumped = true;
    }
    fusion::LineSegment kept = segment;
    kept.t0_m = t0;
    kept.t1_m = t1;
    char text[256];
    std::snprintf(text, sizeof text,
                  "the grid sees through %.3f m of element %s's ends (no occupied cell within one cell): "
                  "cut from %.3f m to %.3f m",
                  cut, element.id().c_str(), length, t1 - t0);
    update_internal::trim_element(result, number, kept, "grid_trimmed", text,
                                  {observation_seq, observer, "grid", "grid", std::nullopt});
  }
  return trim_result;
}

}  // namespace wm::world
