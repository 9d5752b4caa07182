#include "server/world/plan_evidence.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <optional>
#include <stdexcept>
#include <utility>

namespace wm::world {
namespace {

constexpr double kJunctionMinAngleRad = 0.5236;  // 30°: a wall meeting at a shallower angle is a face beside it

void check(const PlanEvidenceOptions& options) {
  if (!(options.step_m > 0) || !std::isfinite(options.step_m))
    throw std::invalid_argument("plan_evidence: step_m must be finite and > 0");
  if (!(options.min_stretch_m >= 0) || !std::isfinite(options.min_stretch_m))
    throw std::invalid_argument("plan_evidence: min_stretch_m must be finite and >= 0");
  if (!(options.junction_cells >= 0) || !std::isfinite(options.junction_cells))
    throw std::invalid_argument("plan_evidence: junction_cells must be finite and >= 0");
  if (options.min_beams_crossing < 0) throw std::invalid_argument("plan_evidence: min_beams_crossing must be >= 0");
}

double point_segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-18), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

/// The range [t0, t1] of t in [0, 1] for which a + t·ab lies in the box (Liang–Barsky); nullopt when none does.
std::optional<std::pair<double, double>> parameters_inside(const Eigen::Vector2d& a, const Eigen::Vector2d& ab,
                                                           const Box& box) {
  double t0 = 0, t1 = 1;
  const auto clip = [&](double from, double step, double lo, double hi) {
    if (step == 0) return from >= lo && from <= hi;
    double u = (lo - from) / step, v = (hi - from) / step;
    if (u > v) std::swap(u, v);
    t0 = std::max(t0, u);
    t1 = std::min(t1, v);
    return t0 <= t1;
  };
  if (!clip(a.x(), ab.x(), box.x0, box.x1) || !clip(a.y(), ab.y(), box.y0, box.y1)) return std::nullopt;
  return std::pair{t0, t1};
}

/// Which samples lie where another drawn edge meets or crosses this one (at 30° or more): there the probe, looking
/// across this edge, finds the other wall's cells whether this one stands or not.
void mark_junctions(const WorldState& state, std::size_t object_index, std::size_t k,
                    const fusion::LineSegment& segment, const std::vector<Eigen::Vector2d>& points,
                    const PlanEvidenceOptions& options, std::vector<bool>& at_junction) {
  at_junction.assign(points.size(), false);
  const double reach = options.junction_cells * options.step_m;
  if (reach <= 0) return;
  const Eigen::Vector2d direction = segment.line.direction();
  const Eigen::Vector2d a = segment.p0(), ab = segment.p1() - a;
  const double count = static_cast<double>(points.size());
  for (const auto& [i, j] : state.objects.edges_near(segment, reach)) {
    if (i == object_index && j == k) continue;
    const auto other = state.objects[i].body.world_edge(j, Eigen::Matrix2d::Zero());
    if (other.length_m() <= 0 || std::abs(direction.dot(other.line.direction())) > std::cos(kJunctionMinAngleRad))
      continue;
    // Only the samples inside the other edge's box grown by the reach can be within reach of it: a long wall
    // crossed by many others tests a few samples per crossing, not all of its samples against each.
    const auto inside = parameters_inside(a, ab, Box::of(other, reach));
    if (!inside) continue;
    const Eigen::Vector2d q0 = other.p0(), q1 = other.p1();
    const auto first = static_cast<std::size_t>(std::clamp(std::floor(inside->first * count - 0.5), 0.0, count));
    const auto last = static_cast<std::size_t>(std::clamp(std::ceil(inside->second * count - 0.5), 0.0, count - 1));
    for (std::size_t n = first; n <= last && n < points.size(); ++n)
      if (!at_junction[n] && point_segment_distance(points[n], q0, q1) <= reach) at_junction[n] = true;
  }
}

/// Junction samples take the verdict of the samples beside them: at an end, the nearest one inside; between two,
/// theirs when both agree (else what the probe said stays). Only from a run of non-junction samples with that verdict
/// at least as long as the junction run: a short wall end (the 30 cm cap of a thick wall) is mostly junction, and
/// one sample in its middle must not speak for all of it.
void fill_junctions(const std::vector<bool>& at_junction, std::vector<EdgeSample>& samples) {
  const std::size_t n = samples.size();
  const std::vector<EdgeSample> probed = samples;
  // The length of the run of equal, non-junction samples that ends (or starts) at i, walking in `step`.
  const auto run_from = [&](std::size_t i, int step) {
    std::size_t length = 0;
    for (auto j = static_cast<std::ptrdiff_t>(i); j >= 0 && j < static_cast<std::ptrdiff_t>(n); j += step) {
      const auto k = static_cast<std::size_t>(j);
      if (at_junction[k] || probed[k] != probed[i]) break;
      ++length;
    }
    return length;
  };
  for (std::size_t i = 0; i < n;) {
    if (!at_junction[i]) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < n && at_junction[j]) ++j;
    const std::size_t junction = j - i;
    std::optional<EdgeSample> fill;
    const bool before = i > 0 && run_from(i - 1, -1) >= junction;
    const bool after = j < n && run_from(j, +1) >= junction;
    if (i > 0 && j < n) {
      if (before && after && probed[i - 1] == probed[j]) fill = probed[j];
    } else if (i > 0) {
      if (before) fill = probed[i - 1];
    } else if (j < n) {
      if (after) fill = probed[j];
    }
    if (fill)
      for (std::size_t m = i; m < j; ++m) samples[m] = *fill;
    i = j;
  }
}

/// The samples of one edge: n equal pieces, each judged at its centre.
std::optional<EdgeEvidence> edge_evidence(const WorldState& state, std::size_t object_index, std::size_t k,
                                          const EdgeProbe& probe, const PlanEvidenceOptions& options,
                                          const EdgeCrossings& crossings, std::vector<EdgeSample>& samples) {
  const ObjectState& object = state.objects[object_index];
  const auto segment = object.body.world_edge(k, Eigen::Matrix2d::Zero());
  const double length = segment.length_m();
  const auto n = static_cast<std::size_t>(std::ceil(length / options.step_m));
  if (n < 2) return std::nullopt;
  const Eigen::Vector2d a = segment.p0(), b = segment.p1();
  const Eigen::Vector2d normal = segment.line.normal();
  std::vector<Eigen::Vector2d> points;
  for (std::size_t i = 0; i < n; ++i)
    points.push_back(a + (static_cast<double>(i) + 0.5) / static_cast<double>(n) * (b - a));
  const double piece = length / static_cast<double>(n);
  samples.clear();
  for (std::size_t i = 0; i < n; ++i) {
    auto sample = probe(points[i], normal);
    if (sample == EdgeSample::unknown && crossings && options.min_beams_crossing > 0) {
      const auto beams = crossings(object_index, k, static_cast<double>(i) * piece, static_cast<double>(i + 1) * piece);
      if (beams.through >= options.min_beams_crossing && beams.through >= 5 * beams.ended)
        sample = EdgeSample::seen_through;
    }
    samples.push_back(sample);
  }
  std::vector<bool> at_junction;
  mark_junctions(state, object_index, k, segment, points, options, at_junction);
  fill_junctions(at_junction, samples);
  std::size_t counts[4] = {0, 0, 0, 0};
  for (const auto sample : samples) ++counts[static_cast<int>(sample)];
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
                                        const PlanEvidenceOptions& options, const EdgeCrossings& crossings) {
  check(options);
  std::vector<EdgeEvidence> result;
  std::vector<EdgeSample> samples;
  for (const auto& [i, k] : state.objects.edges_near(region)) {
    if (!region.crossed_by(state.objects[i].body.world_edge(k, Eigen::Matrix2d::Zero()))) continue;
    if (auto evidence = edge_evidence(state, i, k, probe, options, crossings, samples))
      result.push_back(std::move(*evidence));
  }
  return result;
}

std::vector<EdgeEvidence> plan_evidence(const WorldState& state, const EdgeProbe& probe,
                                        const PlanEvidenceOptions& options, const EdgeCrossings& crossings) {
  check(options);
  std::vector<EdgeEvidence> result;
  std::vector<EdgeSample> samples;
  for (std::size_t i = 0; i < state.objects.size(); ++i) {
    for (std::size_t k = 0; k < state.objects[i].body.edges().size(); ++k)
      if (auto evidence = edge_evidence(state, i, k, probe, options, crossings, samples))
        result.push_back(std::move(*evidence));
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
