#include "server/world/plan_evidence.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wm::world {
namespace {

void check(const PlanEvidenceOptions& options) {
  if (!(options.step_m > 0) || !std::isfinite(options.step_m))
    throw std::invalid_argument("plan_evidence: step_m must be finite and > 0");
  if (!(options.min_stretch_m >= 0) || !std::isfinite(options.min_stretch_m))
    throw std::invalid_argument("plan_evidence: min_stretch_m must be finite and >= 0");
}

/// The samples of one edge: n equal pieces, each judged at its centre.
std::optional<EdgeEvidence> edge_evidence(const ObjectState& object, std::size_t object_index, std::size_t k,
                                          const EdgeProbe& probe, const PlanEvidenceOptions& options,
                                          std::vector<EdgeSample>& samples) {
  const auto segment = object.body.world_edge(k, Eigen::Matrix2d::Zero());
  const double length = segment.length_m();
  const auto n = static_cast<std::size_t>(std::ceil(length / options.step_m));
  if (n < 2) return std::nullopt;
  const Eigen::Vector2d a = segment.p0(), b = segment.p1();
  const Eigen::Vector2d normal = segment.line.normal();
  samples.clear();
  std::size_t counts[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    const double f = (static_cast<double>(i) + 0.5) / static_cast<double>(n);
    const auto sample = probe(a + f * (b - a), normal);
    samples.push_back(sample);
    ++counts[static_cast<int>(sample)];
  }
  EdgeEvidence evidence;
  evidence.object = object_index;
  evidence.edge = k;
  evidence.length_m = length;
  const auto share = [&](EdgeSample s) {
    return static_cast<double>(counts[static_cast<int>(s)]) / static_cast<double>(n);
  };
  evidence.backed = share(EdgeSample::backed);
  evidence.displaced = share(EdgeSample::displaced);
  evidence.seen_through = share(EdgeSample::seen_through);
  evidence.observed = 1.0 - share(EdgeSample::unknown);
  // Runs of seen-through samples; a few unknown samples inside a run (a cell no beam reached between two that many
  // did) do not break it, anything else does. The run ends at its last seen-through sample.
  const double piece = length / static_cast<double>(n);
  for (std::size_t i = 0; i < n;) {
    if (samples[i] != EdgeSample::seen_through) {
      ++i;
      continue;
    }
    std::size_t last = i, j = i + 1, gap = 0;
    for (; j < n; ++j) {
      if (samples[j] == EdgeSample::seen_through) {
        last = j;
        gap = 0;
      } else if (samples[j] == EdgeSample::unknown && ++gap <= options.max_unknown_gap) {
        continue;
      } else {
        break;
      }
    }
    const Stretch stretch{static_cast<double>(i) * piece, static_cast<double>(last + 1) * piece};
    if (stretch.s1_m - stretch.s0_m >= options.min_stretch_m - 1e-9) evidence.seen_through_stretches.push_back(stretch);
    i = last + 1;
  }
  return evidence;
}

}  // namespace

std::vector<EdgeEvidence> plan_evidence(const WorldState& state, const Box& region, const EdgeProbe& probe,
                                        const PlanEvidenceOptions& options) {
  check(options);
  std::vector<EdgeEvidence> result;
  std::vector<EdgeSample> samples;
  for (const auto& [i, k] : state.objects.edges_near(region)) {
    const ObjectState& object = state.objects[i];
    if (!region.crossed_by(object.body.world_edge(k, Eigen::Matrix2d::Zero()))) continue;
    if (auto evidence = edge_evidence(object, i, k, probe, options, samples)) result.push_back(std::move(*evidence));
  }
  return result;
}

std::vector<EdgeEvidence> plan_evidence(const WorldState& state, const EdgeProbe& probe,
                                        const PlanEvidenceOptions& options) {
  check(options);
  std::vector<EdgeEvidence> result;
  std::vector<EdgeSample> samples;
  for (std::size_t i = 0; i < state.objects.size(); ++i) {
    const ObjectState& object = state.objects[i];
    for (std::size_t k = 0; k < object.body.edges().size(); ++k)
      if (auto evidence = edge_evidence(object, i, k, probe, options, samples)) result.push_back(std::move(*evidence));
  }
  return result;
}

const EdgeEvidence* PlanReport::find(std::size_t object, std::size_t edge) const {
  const auto it = std::lower_bound(edges.begin(), edges.end(), std::pair{object, edge},
                                   [](const EdgeEvidence& e, const std::pair<std::size_t, std::size_t>& key) {
                                     return std::pair{e.object, e.edge} < key;
                                   });
  return it != edges.end() && it->object == object && it->edge == edge ? &*it : nullptr;
}

}  // namespace wm::world
