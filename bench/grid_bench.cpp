// Laser scans per second into the occupancy grids (fusion/grid) from a real log, side by side in one run with
// OctoMap inserting the same scans as point clouds and with a raw walk over the same beams' cells (the
// memory-touch limit). Run: build/bin/grid_bench (after cmake -DWM_BUILD_BENCH=ON); another CARMEN log with
// WM_GRID_BENCH_LOG=path. Each iteration builds a fresh map from all scans of the log (loaded once, before timing).
// The same again for dense scans (".../dense"): 1 081 beams 0.25° apart over 270° (a SICK LMS1xx / Hokuyo UTM-class
// lidar), ray-cast along GDC1's robot route inside its plan (tools/raycast, as wm-raycast-log does), where near the
// sensor many beams cross each cell.
#include <benchmark/benchmark.h>
#include <octomap/octomap.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "bench/support/ratio_reporter.h"
#include "fusion/grid/internal/beam_walk.h"
#include "fusion/grid/laser_sonar_grids.h"
#include "fusion/grid/occupancy_grid.h"
#include "logs/carmen_log_reader.h"
#include "tools/raycast/raycast.h"

namespace {

using wm::fusion::GridOptions;
using wm::fusion::LaserScan;

constexpr double kResolutionM = 0.05;

const std::vector<LaserScan>& scans() {
  static const std::vector<LaserScan> all = [] {
    const char* env = std::getenv("WM_GRID_BENCH_LOG");
    const std::string path = env != nullptr ? env : WM_SHARED_DATA_DIR "/carmen/intel-corrected.log.gz";
    wm::logs::CarmenLogReader reader(path);
    std::vector<LaserScan> out;
    while (auto s = reader.next()) out.push_back(std::move(s->scan));
    std::printf("%s: %zu scans\n", path.c_str(), out.size());
    return out;
  }();
  return all;
}

// 1 081 beams over 270° (0.25° apart) every 0.5 m along GDC1's route: the forward 270° of 1 440-beam 360° casts.
const std::vector<LaserScan>& dense_scans() {
  static const std::vector<LaserScan> all = [] {
    const std::string plan = WM_SHARED_DATA_DIR "/amrl-vectormaps/GDC1.vectormap.json";
    wm::raycast::DriveOptions drive;
    drive.beams = 1440;
    std::vector<LaserScan> out =
        wm::raycast::simulate_scans(wm::raycast::read_vectormap(plan), wm::raycast::gdc1_route(), drive);
    constexpr std::size_t kFirst = 180;  // -180° + 180 · 0.25° = -135°
    constexpr std::size_t kBeams = 1081;
    for (LaserScan& s : out) {
      s.angle_min_rad += static_cast<double>(kFirst) * s.angle_increment_rad;
      s.ranges_m = std::vector<double>(s.ranges_m.begin() + kFirst, s.ranges_m.begin() + kFirst + kBeams);
    }
    std::printf("%s: %zu ray-cast scans of %zu beams over 270 deg\n", plan.c_str(), out.size(), kBeams);
    return out;
  }();
  return all;
}

// Which scans a benchmark inserts.
using ScanSet = const std::vector<LaserScan>& (*)();

GridOptions options(double beam_width_deg, bool bayes, bool ds) {
  GridOptions o;
  o.resolution_m = kResolutionM;
  o.sensor.laser_beam_width_rad = beam_width_deg * std::numbers::pi / 180.0;
  o.update_bayes = bayes;
  o.update_ds = ds;
  return o;
}

// Cell visits of one pass over the log (the same for the raw walk and the grids).
std::size_t cells_per_pass(ScanSet set, const GridOptions& o) {
  std::size_t cells = 0;
  for (const LaserScan& s : set()) {
    for (std::size_t i = 0; i < s.ranges_m.size(); ++i) {
      if (const auto beam = wm::fusion::laser_beam(s, i, o.sensor)) {
        cells += wm::fusion::beam_cells(*beam, o.resolution_m).size();
      }
    }
  }
  return cells;
}

// items/s: scans/s; beams/s counts every reading (a scan's beams, whatever they read); cells/s the cell visits.
void set_counters(benchmark::State& state, ScanSet set, std::size_t cells) {
  const auto iterations = static_cast<double>(state.iterations());
  std::size_t beams = 0;
  for (const LaserScan& s : set()) beams += s.ranges_m.size();
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * set().size()));
  state.counters["beams/s"] = benchmark::Counter(static_cast<double>(beams) * iterations, benchmark::Counter::kIsRate);
  if (cells > 0) {
    state.counters["cells/s"] =
        benchmark::Counter(static_cast<double>(cells) * iterations, benchmark::Counter::kIsRate);
  }
}

void bm_grid(benchmark::State& state, ScanSet set, GridOptions o) {
  const std::size_t cells = cells_per_pass(set, o);
  for (auto _ : state) {
    wm::fusion::OccupancyGrid grid(o);
    for (const LaserScan& s : set()) grid.insert(s);
    benchmark::DoNotOptimize(grid.log_odds({0, 0}));
  }
  set_counters(state, set, cells);
}

// A sonar ring beside each laser scan (the log has none): 16 transducers with 30° cones, each reading the laser's
// shortest return within its cone (capped at 6 m), every 17th reading a cross-talk phantom at a third of it.
const std::vector<wm::fusion::SonarScan>& sonar_rings() {
  static const std::vector<wm::fusion::SonarScan> all = [] {
    std::vector<wm::fusion::SonarScan> out;
    std::size_t n = 0;
    for (const LaserScan& s : scans()) {
      wm::fusion::SonarScan ring;
      ring.sensor_pose = s.sensor_pose;
      ring.beam_width_rad = 30 * std::numbers::pi / 180;
      ring.range_min_m = 0.15;
      ring.range_max_m = 6.0;
      for (int k = 0; k < 16; ++k) {
        const double axis = 2 * std::numbers::pi * k / 16;
        double reading = ring.range_max_m;
        for (std::size_t i = 0; i < s.ranges_m.size(); ++i) {
          const double a = s.angle_min_rad + static_cast<double>(i) * s.angle_increment_rad;
          if (std::abs(std::remainder(a - axis, 2 * std::numbers::pi)) <= ring.beam_width_rad / 2 &&
              s.ranges_m[i] >= s.range_min_m && s.ranges_m[i] < s.range_max_m)
            reading = std::min(reading, s.ranges_m[i]);
        }
        if (++n % 17 == 0) reading = std::max(ring.range_min_m, reading / 3);
        ring.angles_rad.push_back(axis);
        ring.ranges_m.push_back(reading);
      }
      out.push_back(std::move(ring));
    }
    return out;
  }();
  return all;
}

// Laser scans and sonar rings into the fused, laser-only and sonar-only grids, the sonar judged by the laser or not.
void bm_laser_sonar(benchmark::State& state, bool gated) {
  const auto& rings = sonar_rings();
  wm::fusion::LaserSonarOptions o;
  o.gate_sonar = gated;
  for (auto _ : state) {
    wm::fusion::LaserSonarGrids grids(options(2.0, true, true), o);
    for (std::size_t k = 0; k < scans().size(); ++k) {
      grids.insert(scans()[k]);
      grids.insert(rings[k]);
    }
    benchmark::DoNotOptimize(grids.fused().log_odds({0, 0}));
    state.counters["phantoms"] = static_cast<double>(grids.gate_counts().phantom);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * scans().size()));
}

// The raw baseline: the same walk over the same cells (same beams, same cone, same classification), each visit
// only adding a constant to a float in one dense array covering the whole log — no tiles, no scan stamps, no
// per-scan bookkeeping, no sensor model. What touching those cells costs at least.
void bm_raw_walk(benchmark::State& state, ScanSet set, GridOptions o) {
  const std::size_t cells = cells_per_pass(set, o);
  // Dense bounds: every sensor position ± the walked distance.
  double x0 = std::numeric_limits<double>::max(), y0 = x0, x1 = -x0, y1 = -x0;
  for (const LaserScan& s : set()) {
    x0 = std::min(x0, s.sensor_pose.x_m);
    y0 = std::min(y0, s.sensor_pose.y_m);
    x1 = std::max(x1, s.sensor_pose.x_m);
    y1 = std::max(y1, s.sensor_pose.y_m);
  }
  const double margin = o.sensor.max_usable_range_m + 1.0;
  const auto cx0 = static_cast<std::int64_t>(std::floor((x0 - margin) / kResolutionM));
  const auto cy0 = static_cast<std::int64_t>(std::floor((y0 - margin) / kResolutionM));
  const auto width = static_cast<std::int64_t>(std::ceil((x1 + margin) / kResolutionM)) - cx0;
  const auto height = static_cast<std::int64_t>(std::ceil((y1 + margin) / kResolutionM)) - cy0;
  for (auto _ : state) {
    std::vector<float> grid(static_cast<std::size_t>(width * height), 0.f);
    for (const LaserScan& s : set()) {
      for (std::size_t i = 0; i < s.ranges_m.size(); ++i) {
        const auto beam = wm::fusion::laser_beam(s, i, o.sensor);
        if (!beam) continue;
        const auto b = wm::fusion::internal::prepare(*beam, kResolutionM);
        wm::fusion::internal::for_each_beam_cell(
            b, [&](std::int64_t x, std::int64_t y, double, wm::fusion::internal::CellClass cls) {
              grid[static_cast<std::size_t>((y - cy0) * width + (x - cx0))] +=
                  cls == wm::fusion::internal::CellClass::hit ? 0.85f : -0.4f;
            });
      }
    }
    benchmark::DoNotOptimize(grid.data());
  }
  set_counters(state, set, cells);
}

// OctoMap 1.9 at the same resolution: each scan as a point cloud in the z = 0 plane, inserted from the sensor
// origin with maxrange = the grids' usable range (beyond it: free up to maxrange, no hit — the grids' rule).
// "No return" readings become far points, so they clear up to maxrange as in the grids.
void bm_octomap(benchmark::State& state, ScanSet set) {
  const GridOptions o = options(0.0, true, false);
  std::vector<std::pair<octomap::point3d, octomap::Pointcloud>> clouds;
  for (const LaserScan& s : set()) {
    octomap::Pointcloud cloud;
    for (std::size_t i = 0; i < s.ranges_m.size(); ++i) {
      const double r = s.ranges_m[i];
      if (!(r >= s.range_min_m)) continue;  // NaN, negative, too short: ignored as in the grids
      const double reach = r >= s.range_max_m ? 2.0 * o.sensor.max_usable_range_m : r;
      const double a = s.sensor_pose.theta_rad + s.angle_min_rad + static_cast<double>(i) * s.angle_increment_rad;
      cloud.push_back(static_cast<float>(s.sensor_pose.x_m + reach * std::cos(a)),
                      static_cast<float>(s.sensor_pose.y_m + reach * std::sin(a)), 0.f);
    }
    clouds.emplace_back(
        octomap::point3d(static_cast<float>(s.sensor_pose.x_m), static_cast<float>(s.sensor_pose.y_m), 0.f),
        std::move(cloud));
  }
  for (auto _ : state) {
    octomap::OcTree tree(kResolutionM);
    for (const auto& [origin, cloud] : clouds) tree.insertPointCloud(cloud, origin, o.sensor.max_usable_range_m);
    benchmark::DoNotOptimize(tree.size());
  }
  set_counters(state, set, 0);
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  scans();  // load before timing
  dense_scans();
  for (const auto& [set, suffix] : {std::pair<ScanSet, std::string>{scans, ""}, {dense_scans, "/dense"}}) {
    for (const double width : {2.0, 0.0}) {
      const std::string w = (width > 0.0 ? "/2deg" : "/thin") + suffix;
      benchmark::RegisterBenchmark(("raw_walk" + w).c_str(), bm_raw_walk, set, options(width, true, false))
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(("bayes" + w).c_str(), bm_grid, set, options(width, true, false))
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(("ds" + w).c_str(), bm_grid, set, options(width, false, true))
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(("bayes+ds" + w).c_str(), bm_grid, set, options(width, true, true))
          ->Unit(benchmark::kMillisecond);
    }
    benchmark::RegisterBenchmark(("octomap" + suffix).c_str(), bm_octomap, set)->Unit(benchmark::kMillisecond);
  }
  benchmark::RegisterBenchmark("laser+sonar_ungated", bm_laser_sonar, false)->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("laser+sonar_gated", bm_laser_sonar, true)->Unit(benchmark::kMillisecond);

  // A baseline with a suffix is compared only with the benchmarks of that suffix (the dense ones with each other).
  wm::bench::RatioReporter reporter({{"vs OctoMap", "octomap"},
                                     {"vs raw walk (2deg)", "raw_walk/2deg"},
                                     {"vs Bayes (2deg)", "bayes/2deg"},
                                     {"vs OctoMap (dense scans)", "octomap/dense"},
                                     {"vs raw walk (2deg, dense scans)", "raw_walk/2deg/dense"},
                                     {"vs Bayes (2deg, dense scans)", "bayes/2deg/dense"},
                                     {"vs laser+sonar ungated", "laser+sonar_ungated"}});
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();

  // The targets, measured in this run.
  const auto ratio = [&](const std::string& a, const std::string& b) {
    const double rb = reporter.rate(b);
    return rb > 0.0 ? reporter.rate(a) / rb : 0.0;
  };
  std::printf("\nTargets, scans/s ratios of this run:\n");
  for (const std::string suffix : {"", "/dense"}) {
    for (const char* width : {"/2deg", "/thin"}) {
      const std::string w = width + suffix;
      const std::string label = (width + 1) + (suffix.empty() ? std::string(" Intel") : std::string(" dense"));
      std::printf("  %-11s Bayes / OctoMap  = %7.2f  (target >= 30)\n", label.c_str(),
                  ratio("bayes" + w, "octomap" + suffix));
      std::printf("  %-11s Bayes / raw walk = %7.2f  (target >= 0.5, i.e. within 2x)\n", label.c_str(),
                  ratio("bayes" + w, "raw_walk" + w));
      std::printf("  %-11s DS / Bayes       = %7.2f  (target >= 0.5, i.e. within 2x)\n", label.c_str(),
                  ratio("ds" + w, "bayes" + w));
    }
  }
  return 0;
}
