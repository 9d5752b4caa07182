// Cost of one primitive's update (match, decide, fuse, maintain: world::apply_observation) as the map grows:
// 100, 1 000, 10 000 and 100 000 observed elements, and a 6 000-edge floor plan. The target is at most 2× from
// the smallest map to the largest; the ratios to the 100-element map are printed after the table. Decisions come
// from a C++ stand-in for the shipped rules (merge a matched element, confirm a matched edge, add otherwise), so
// the figure is the world update without Prolog (rules_bench measures that).
// Run: build/bin/world_update_bench (after cmake -DWM_BUILD_BENCH=ON).
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <random>
#include <vector>

#include "bench/support/ratio_reporter.h"
#include "server/world/update.h"

namespace {

using wm::world::Observation;
using wm::world::WorldOptions;
using wm::world::WorldState;

constexpr double kSpacingM = 3.0;  // elements lie on a square lattice, one 1.5 m wall per cell

wm::fusion::LineSegment wall_at(double x, double y, double angle, const WorldOptions& o) {
  const Eigen::Vector2d d(std::cos(angle), std::sin(angle));
  auto s = wm::fusion::LineSegment::from_points({x, y}, Eigen::Vector2d(x, y) + 1.5 * d, Eigen::Matrix2d::Identity());
  s.line.cov = wm::world::midpoint_line_cov(s, o.default_offset_sigma_m, o.default_angle_sigma_rad);
  return s;
}

// A map of `n` elements, and observations: 64 requests of 8 segments, half on existing walls, half in empty cells.
struct Scene {
  WorldState state;
  std::vector<Observation> observations;
};

Scene make_scene(std::size_t n, std::size_t plan_rooms) {
  Scene scene;
  WorldOptions options;
  const auto side = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(n))));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(0.0, 3.14159);
  std::vector<double> angles;
  for (std::size_t i = 0; i < n; ++i) {
    wm::world::Element e;
    e.number = static_cast<std::int64_t>(i + 1);
    angles.push_back(angle(rng));
    e.segment = wall_at(kSpacingM * static_cast<double>(i % side), kSpacingM * static_cast<double>(i / side),
                        angles.back(), options);
    e.moments = wm::fusion::SegmentMoments::of(e.segment);
    e.origin = "scan";
    e.observer = "bench";
    scene.state.elements.put(std::move(e));
  }
  scene.state.next_element_number = static_cast<std::int64_t>(n + 1);
  if (plan_rooms > 0) {
    wm::apriori::FloorPlan plan{"bench", {}};
    for (std::size_t r = 0; r < plan_rooms; ++r) {
      wm::apriori::PlanObject wall;
      wall.id = "room-" + std::to_string(r);
      wall.kind = "wall";
      wall.attributes = {"solid"};
      const double x = -10.0 - 6.0 * static_cast<double>(r % 40), y = -10.0 - 6.0 * static_cast<double>(r / 40);
      wall.polylines = {{{x, y}, {x - 5, y}, {x - 5, y - 5}, {x, y - 5}, {x, y}}};
      plan.objects.push_back(wall);
    }
    scene.state = wm::world::apply_floor_plan(scene.state, plan, options).state;
  }
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  std::normal_distribution<double> noise(0.0, 0.005);
  for (int r = 0; r < 64; ++r) {
    Observation o;
    o.observer = "bench";
    o.origin = "scan";
    for (int k = 0; k < 8; ++k) {
      const std::size_t i = pick(rng);
      const double x = kSpacingM * static_cast<double>(i % side), y = kSpacingM * static_cast<double>(i / side);
      // Even: a view of wall i; odd: a new wall in the middle of its cell.
      const auto s = k % 2 == 0 ? wall_at(x + noise(rng), y + noise(rng), angles[i], options)
                                : wall_at(x + 1.5, y + 1.5, angles[i] + 1.0, options);
      o.segments.push_back({s});
    }
    scene.observations.push_back(std::move(o));
  }
  return scene;
}

wm::rules::Decision stand_in_rules(const wm::rules::DecisionQuery& q) {
  if (!q.element_id) return {"add", "unmatched_added", "", false};
  if (q.object_id) return {"delete", "solid_confirmed", "", false};
  return {"merge", q.origin == "element" ? "elements_merged" : "unknown_element_merged", "", false};
}

void update_per_primitive(benchmark::State& state, std::size_t elements, std::size_t plan_rooms) {
  const Scene scene = make_scene(elements, plan_rooms);  // before the timed loop
  const WorldOptions options;
  std::size_t i = 0;
  for (auto _ : state) {
    auto result = wm::world::apply_observation(scene.state, scene.observations[i++ % scene.observations.size()], 1,
                                               options, stand_in_rules);
    benchmark::DoNotOptimize(result);
  }
  state.SetItemsProcessed(state.iterations() * 8);  // primitives
}

}  // namespace

int main(int argc, char** argv) {
  for (const std::size_t n : {100, 1000, 10000, 100000})
    benchmark::RegisterBenchmark(("update_" + std::to_string(n) + "_elements").c_str(), update_per_primitive, n, 0)
        ->Unit(benchmark::kMicrosecond);
  // 1 500 rooms of 4 walls: a 6 000-edge plan, with 100 elements.
  benchmark::RegisterBenchmark("update_100_elements_6000_plan_edges", update_per_primitive, 100, 1500)
      ->Unit(benchmark::kMicrosecond);
  return wm::bench::run_with_ratios(argc, argv, {{"against the 100-element map", "update_100_elements"}});
}
