// Placing a floor plan on a grid (fusion::register_plan), ±10 m and ±180° at scale 1:
//  - the real GDC1 plan (1 289 edges) against the Bayes grid a 360° laser ray-cast along GDC1's robot route
//    fills (about 1 400 × 1 300 cells of 5 cm);
//  - a 6 000-edge plan (1 500 rooms of irregular sizes) against a raster of its own walls.
//  - AHG2's plan on GDC1's grid (a wrong building): the time until the answer scores below 0.5 (low_score).
// Every case runs on all cores and, as its named baseline, on one thread (ratios in items/s of wall-clock time).
// Baseline: the same branch and bound over every angle of the bound (Cartographer's fast correlative matcher,
// Hess et al. 2016), without the direction-histogram candidates; and, for the refinement alone, a search of ±0.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <cstdlib>
#include <random>
#include <string>
#include <thread>
#include <utility>

#include "bench/support/ratio_reporter.h"
#include "fusion/grid/occupancy_grid.h"
#include "fusion/registration/plan_registration.h"
#include "tools/raycast/raycast.h"

namespace {

using wm::fusion::DrawnEdge;
using wm::fusion::ObservedMap;
using wm::fusion::RegistrationOptions;
using wm::fusion::Similarity2D;

struct Case {
  std::vector<DrawnEdge> edges;  // drawn displaced
  ObservedMap observed;
  Similarity2D truth;
};

// The drawing of `lines` that `truth` places back on them.
std::vector<DrawnEdge> drawn(const std::vector<wm::raycast::PlanLine>& lines, const Similarity2D& truth) {
  std::vector<DrawnEdge> edges;
  for (const auto& l : lines)
    edges.push_back({truth.inverse_transform_point(l.p0), truth.inverse_transform_point(l.p1)});
  return edges;
}

const Case& gdc1() {
  static const Case c = [] {
    const auto lines = wm::raycast::read_vectormap(WM_PLANS_DIR "/GDC1.vectormap.json");
    wm::fusion::OccupancyGrid grid(wm::fusion::GridOptions{});
    for (const auto& scan : wm::raycast::simulate_scans(lines, wm::raycast::gdc1_route())) grid.insert(scan);
    const auto bounds = *grid.bounds();
    const Similarity2D truth{4.0, -6.0, 2.6, 1.0};
    return Case{drawn(lines, truth),
                {bounds, grid.export_layer(wm::fusion::OccupancyGrid::Layer::bayes_probability, bounds), {}},
                truth};
  }();
  return c;
}

// 1 500 rooms in rows of random widths (2-6 m) and depths (3-6 m), every room its 4 walls; the raster holds the
// walls as occupied cells and the rest of the floor as seen free.
const Case& plan_6000() {
  static const Case c = [] {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> width(2.0, 6.0), depth(3.0, 6.0);
    std::vector<wm::raycast::PlanLine> lines;
    double y = 0;
    int rooms = 0;
    while (rooms < 1500) {
      const double d = depth(rng);
      double x = 0;
      for (int k = 0; k < 38 && rooms < 1500; ++k, ++rooms) {
        const double w = width(rng);
        const Eigen::Vector2d a(x, y), b(x + w, y), c2(x + w, y + d), e(x, y + d);
        lines.insert(lines.end(), {{a, b}, {b, c2}, {c2, e}, {e, a}});
        x += w + 0.2;
      }
      y += d + 2.0;  // a corridor between rows
    }
    double max_x = 0, max_y = 0;
    for (const auto& l : lines) {
      max_x = std::max({max_x, l.p0.x(), l.p1.x()});
      max_y = std::max({max_y, l.p0.y(), l.p1.y()});
    }
    const wm::fusion::GridGeometry g({-1, -1}, 0.05, static_cast<std::int64_t>((max_x + 2) / 0.05),
                                     static_cast<std::int64_t>((max_y + 2) / 0.05));
    std::vector<float> p(static_cast<std::size_t>(g.width() * g.height()), 0.2f);
    for (const auto& l : lines) {
      const int n = static_cast<int>((l.p1 - l.p0).norm() / 0.025) + 1;
      for (int i = 0; i <= n; ++i) {
        const auto cell = g.cell_of(l.p0 + (l.p1 - l.p0) * (static_cast<double>(i) / n));
        p[static_cast<std::size_t>(cell.y * g.width() + cell.x)] = 0.9f;
      }
    }
    const Similarity2D truth{-3.0, 5.0, -1.2, 1.0};
    return Case{drawn(lines, truth), {g, std::move(p), {}}, truth};
  }();
  return c;
}

// AHG2's plan (another building of the same campus) on GDC1's grid, centred on the area the robots saw: nothing
// fits, the answer must be low_score (the server's default min_score, 0.5).
const Case& wrong_building() {
  static const Case c = [] {
    const auto other = wm::raycast::read_vectormap(WM_PLANS_DIR "/AHG2.vectormap.json");
    Case w{{}, gdc1().observed, {}};
    for (const auto& l : other) w.edges.push_back({l.p0 - Eigen::Vector2d(40, 50), l.p1 - Eigen::Vector2d(40, 50)});
    return w;
  }();
  return c;
}

void wrong(benchmark::State& state, const Case& (*make)(), unsigned threads) {
  const Case& c = make();
  RegistrationOptions options;
  options.threads = threads;
  options.time_budget = std::chrono::milliseconds(600000);
  wm::fusion::RegistrationResult r;
  for (auto _ : state) {
    r = wm::fusion::register_plan(c.edges, c.observed, options);
    benchmark::DoNotOptimize(r);
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["edges"] = static_cast<double>(c.edges.size());
  state.counters["score"] = r.best.score;
  state.counters["coverage"] = r.best.coverage;
  state.counters["low_score"] = r.best.score < 0.5;
  state.counters["hypotheses"] = static_cast<double>(r.hypotheses_scored);
  state.counters["search_score"] = r.search_score;
}

void align(benchmark::State& state, const Case& (*make)(), bool from_directions, double max_translation_m,
           double max_rotation_rad, unsigned threads) {
  const Case& c = make();
  RegistrationOptions options;
  options.threads = threads;
  options.max_translation_m = max_translation_m;
  options.max_rotation_rad = max_rotation_rad;
  options.rotations_from_directions = from_directions;
  options.time_budget = std::chrono::milliseconds(600000);
  double error = 0;
  wm::fusion::RegistrationResult r;
  for (auto _ : state) {
    r = wm::fusion::register_plan(c.edges, c.observed, options);
    benchmark::DoNotOptimize(r);
  }
  for (const auto& e : c.edges)
    error = std::max(error, (r.best.placement.transform_point(e.p0) - c.truth.transform_point(e.p0)).norm());
  state.SetItemsProcessed(state.iterations());
  state.counters["edges"] = static_cast<double>(c.edges.size());
  state.counters["cells"] = static_cast<double>(c.observed.probability.size());
  state.counters["worst_error_m"] = error;
  state.counters["score"] = r.best.score;
  state.counters["ambiguous"] = r.ambiguous;
  state.counters["search_score"] = r.search_score;
  state.counters["hypotheses"] = static_cast<double>(r.hypotheses_scored);
}

}  // namespace

int main(int argc, char** argv) {
  constexpr double kPi = 3.14159265358979323846;
  // Every case on all cores and on one thread (the named baselines: the same search, single-threaded).
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  for (const auto& [name, threads] : {std::pair<std::string, unsigned>{"", cores}, {"_1Thread", 1u}}) {
    benchmark::RegisterBenchmark(("BM_AlignGdc1_10m_180deg" + name).c_str(), align, &gdc1, true, 10.0, kPi, threads)
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond)
        ->Iterations(5);
    benchmark::RegisterBenchmark(("BM_AlignPlan6000_10m_180deg" + name).c_str(), align, &plan_6000, true, 10.0, kPi,
                                 threads)
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond)
        ->Iterations(3);
    benchmark::RegisterBenchmark(("BM_WrongBuilding_10m_180deg" + name).c_str(), wrong, &wrong_building, threads)
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond)
        ->Iterations(3);
  }
  if (!std::getenv("WM_BENCH_QUICK"))  // the longest case by far
    benchmark::RegisterBenchmark("BM_AlignGdc1_10m_180deg_EveryAngle", align, &gdc1, false, 10.0, kPi, cores)
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond)
        ->Iterations(1);

  return wm::bench::run_with_ratios(
      argc, argv,
      {{"GDC1 against one thread", "BM_AlignGdc1_10m_180deg_1Thread"},
       {"6 000 edges against one thread", "BM_AlignPlan6000_10m_180deg_1Thread"},
       {"wrong building against one thread", "BM_WrongBuilding_10m_180deg_1Thread"},
       {"against branch and bound over every angle", "BM_AlignGdc1_10m_180deg_EveryAngle"}});
}
