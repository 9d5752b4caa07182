#include <algorithm>
#include <cmath>
#include <cstdint>

#include "fusion/registration/plan_registration.h"
#include "fusion/registration/plan_registration_internal.h"

namespace wm::fusion {
namespace internal {

std::vector<Eigen::Vector2d> sample_edges(const std::vector<DrawnEdge>& edges, std::size_t count) {
  std::vector<Eigen::Vector2d> samples;
  const double length = total_length(edges);
  if (length <= 0 || count == 0) return samples;
  const double step = length / static_cast<double>(count);
  samples.reserve(count + edges.size());
  double carry = 0.5 * step;  // distance from the start of the next edge to its first sample
  for (const auto& e : edges) {
    const double l = (e.p1 - e.p0).norm();
    for (double t = carry; t < l; t += step) samples.push_back(e.p0 + (e.p1 - e.p0) * (t / l));
    const double past = l - carry;
    carry = past < 0 ? -past : step - std::fmod(past, step);
    if (carry <= 0 || carry > step) carry = step;
  }
  return samples;
}

}  // namespace internal

using namespace internal;

PlacementHypothesis score_placement(const std::vector<DrawnEdge>& edges, const ObservedMap& observed,
                                    const Similarity2D& placement, double occupied_probability) {
  const auto& g = observed.geometry;
  const double length_m = total_length(edges) * placement.scale;
  const auto count = static_cast<std::size_t>(std::clamp(length_m / g.resolution_m(), 1.0, 2.0e6));
  const auto samples = sample_edges(edges, count);
  std::size_t known = 0, on = 0;
  for (const auto& s : samples) {
    const auto w = placement.transform_point(s);
    if (!finite(w)) continue;
    const auto c = g.cell_of(w);
    bool seen = false, occupied = false;
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const CellIndex n{c.x + dx, c.y + dy};
        if (!g.contains(n)) continue;
        const float p = observed.probability[static_cast<std::size_t>(n.y * g.width() + n.x)];
        if (std::isnan(p)) continue;
        seen = true;
        occupied = occupied || p > occupied_probability;
      }
    known += seen;
    on += occupied;
  }
  PlacementHypothesis h{placement, 0, 0};
  if (!samples.empty()) h.coverage = static_cast<double>(known) / static_cast<double>(samples.size());
  if (known > 0) h.score = static_cast<double>(on) / static_cast<double>(known);
  return h;
}

}  // namespace wm::fusion
