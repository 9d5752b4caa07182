// Decisions per second through the knowledge base, side by side with the same four rules hard-coded in
// C++ (the seed paper's original if-then-else) and with the full C++ per-primitive update (matching +
// Kalman fusion). Run: build/bin/rules_bench (after cmake -DWM_BUILD_BENCH=ON).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "bench/support/ratio_reporter.h"
#include "rules/engine.h"
#include "server/world/update.h"

namespace {

using wm::rules::Decision;
using wm::rules::DecisionQuery;

// A plan of `rooms` rooms along a corridor: four solid walls each and a not_deformable table.
wm::apriori::FloorPlan corridor(int rooms) {
  wm::apriori::FloorPlan plan{"bench", {}};
  for (int i = 0; i < rooms; ++i) {
    const double x = 6.0 * i;
    wm::apriori::PlanObject wall;
    wall.id = "wall-" + std::to_string(i);
    wall.kind = "wall";
    wall.attributes = {"solid"};
    wall.polylines = {{{x, 0}, {x + 5, 0}, {x + 5, 5}, {x, 5}, {x, 0}}};
    wm::apriori::PlanObject table;
    table.id = "table-" + std::to_string(i);
    table.kind = "table";
    table.attributes = {"not_deformable"};
    table.pose = {x + 2.5, 2.5, 0.2};
    table.polygon = {{-0.6, -0.4}, {0.6, -0.4}, {0.6, 0.4}, {-0.6, 0.4}};
    plan.objects.push_back(wall);
    plan.objects.push_back(table);
  }
  return plan;
}

// The realistic mix of questions: walls confirmed (half), observed elements, tables, new lines.
std::vector<DecisionQuery> query_mix(std::size_t n) {
  std::vector<DecisionQuery> queries;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> d2(0.0, 5.0);
  for (std::size_t i = 0; i < n; ++i) {
    DecisionQuery q;
    q.observer = "robot-1";
    q.rho_m = 2.0 + 0.01 * static_cast<double>(i % 100);
    q.phi_rad = 0.3;
    q.length_m = 1.5;
    q.origin = "scan";
    q.sensor = "laser";
    const auto room = std::to_string(i % 50);
    switch (i % 8) {
      case 0:
      case 1:
      case 2:
      case 3:
        q.element_id = "wall-" + room + "/1";
        q.object_id = "wall-" + room;
        q.mahalanobis_sq = d2(rng);
        break;
      case 4:
      case 5:
        q.element_id = "e" + room;
        q.mahalanobis_sq = d2(rng);
        break;
      case 6:
        q.element_id = "table-" + room + "/0";
        q.object_id = "table-" + room;
        q.mahalanobis_sq = d2(rng);
        break;
      default:
        break;
    }
    queries.push_back(q);
  }
  return queries;
}

std::vector<wm::rules::ObjectFacts> facts_of(const wm::world::WorldState& state,
                                             const wm::world::WorldOptions& options) {
  std::vector<wm::rules::ObjectFacts> result;
  for (const auto& object : state.objects) {
    wm::rules::ObjectFacts f{object.plan->id, object.plan->kind, object.plan->attributes, {}};
    for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
      const auto edge = wm::world::apriori_edge(object, k, options);
      f.edges.push_back({wm::world::edge_id(f.id, k), edge.line.rho_m, edge.line.phi_rad, edge.length_m()});
    }
    result.push_back(std::move(f));
  }
  return result;
}

struct Fixture {
  wm::world::WorldOptions options;
  wm::world::WorldState state;
  wm::rules::Engine engine;
  std::vector<DecisionQuery> queries = query_mix(4096);

  Fixture()
      : state(wm::world::apply_floor_plan({}, corridor(50), options).state),
        engine(wm::rules::EngineOptions{WM_RULES_DIR, 200000, 1.0}) {
    engine.set_floor_plan(facts_of(state, options));
  }
};

Fixture& fixture() {
  static Fixture f;  // one Prolog runtime per process
  return f;
}

// The same rules as rules/prolog/world_model.pl, as the paper wrote them: if/else in C++, with the same
// explanation text (a decision that cannot explain itself is not the same product).
Decision cpp_rules(const DecisionQuery& q, const wm::world::WorldState& state) {
  char text[256];
  if (!q.element_id) {
    std::snprintf(text, sizeof text,
                  "%s observed a line (rho = %.4f m, phi = %.4f rad, length = %.4f m) that matches nothing: added as a "
                  "new element",
                  q.observer.c_str(), q.rho_m, q.phi_rad, q.length_m);
    return {"add", "unmatched_added", text, false};
  }
  if (!q.object_id) {
    std::snprintf(text, sizeof text,
                  "%s matched element %s, which is not in the floor plan (d2 = %.4f): merged by Kalman fusion",
                  q.observer.c_str(), q.element_id->c_str(), q.mahalanobis_sq);
    return {"merge", "unknown_element_merged", text, false};
  }
  const auto* object = state.find_object(*q.object_id);
  if (object && object->plan->has_attribute("solid")) {
    std::snprintf(
        text, sizeof text,
        "%s matched element %s of solid object %s (d2 = %.4f): the plan is confirmed, the observation is deleted",
        q.observer.c_str(), q.element_id->c_str(), q.object_id->c_str(), q.mahalanobis_sq);
    return {"delete", "solid_confirmed", text, false};
  }
  if (object && object->plan->has_attribute("not_deformable")) {
    std::snprintf(
        text, sizeof text,
        "%s matched element %s of not_deformable object %s (d2 = %.4f): the object's pose is adjusted, its shape kept",
        q.observer.c_str(), q.element_id->c_str(), q.object_id->c_str(), q.mahalanobis_sq);
    return {"rigid_adjust", "not_deformable_rigid", text, false};
  }
  return {"delete", "apriori_confirmed", "confirmed", false};
}

void BM_PrologDecideOneAtATime(benchmark::State& state) {
  auto& f = fixture();
  std::size_t i = 0;
  for (auto _ : state) {
    auto d = f.engine.decide(f.queries[i++ % f.queries.size()]);
    benchmark::DoNotOptimize(d);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_PrologDecideOneAtATime);

void BM_PrologDecideBatched(benchmark::State& state) {
  auto& f = fixture();
  const auto n = static_cast<std::size_t>(state.range(0));
  const std::vector<DecisionQuery> batch(f.queries.begin(), f.queries.begin() + static_cast<std::ptrdiff_t>(n));
  for (auto _ : state) {
    auto d = f.engine.decide_batch(batch);
    benchmark::DoNotOptimize(d);
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_PrologDecideBatched)->Arg(100)->Arg(1000);

void BM_CppIfElseRules(benchmark::State& state) {
  auto& f = fixture();
  std::size_t i = 0;
  for (auto _ : state) {
    auto d = cpp_rules(f.queries[i++ % f.queries.size()], f.state);
    benchmark::DoNotOptimize(d);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_CppIfElseRules);

// The full per-primitive update (match against every edge and element, decide, Kalman fusion / EKF),
// deciding with the C++ rules so that the figure is the cost without Prolog.
void BM_FullUpdatePerPrimitive(benchmark::State& state) {
  auto& f = fixture();
  // Primitives along the walls of the rooms and free lines inside them.
  std::vector<wm::world::Observation> observations;
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.005);
  for (int i = 0; i < 256; ++i) {
    const double x = 6.0 * (i % 50);
    wm::world::Observation o;
    o.observer = "robot-1";
    Eigen::Vector2d a, b;
    if (i % 2 == 0) {
      a = {x + 1.0, noise(rng)};
      b = {x + 4.0, noise(rng)};
    } else {
      a = {x + 1.0, 4.0 + noise(rng)};
      b = {x + 1.0 + noise(rng), 1.0};
    }
    auto s = wm::fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
    s.line.cov = wm::world::midpoint_line_cov(s, f.options.default_offset_sigma_m, f.options.default_angle_sigma_rad);
    o.segments.push_back({s});
    observations.push_back(o);
  }
  const wm::world::Decide decide = [&](const DecisionQuery& q) { return cpp_rules(q, f.state); };
  std::size_t i = 0;
  for (auto _ : state) {
    auto r = wm::world::apply_observation(f.state, observations[i % observations.size()],
                                          static_cast<std::int64_t>(i + 1), f.options, decide);
    ++i;
    benchmark::DoNotOptimize(r);
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["map_edges"] = static_cast<double>(f.state.objects.size() * 4);
}
BENCHMARK(BM_FullUpdatePerPrimitive);

}  // namespace

int main(int argc, char** argv) {
  return wm::bench::run_with_ratios(argc, argv,
                                    {{"against the C++ if/else rules", "BM_CppIfElseRules"},
                                     {"against the full per-primitive update", "BM_FullUpdatePerPrimitive"}});
}
