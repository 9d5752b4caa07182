// Scan line extraction per scan on the real Intel log, side by side with inserting the same scan into the
// Bayes grid (the other thing every laser scan costs the server). Run: build-bench/bin/scan_lines_bench.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench/support/ratio_reporter.h"
#include "fusion/grid/occupancy_grid.h"
#include "fusion/lines/scan_lines.h"
#include "logs/carmen_log_reader.h"

namespace {

const std::vector<wm::fusion::LaserScan>& scans() {
  static const std::vector<wm::fusion::LaserScan> all = [] {
    const char* env = std::getenv("WM_SCAN_LINES_BENCH_LOG");
    wm::logs::CarmenLogReader reader(env != nullptr ? env : WM_SHARED_DATA_DIR "/carmen/intel-corrected.log.gz");
    std::vector<wm::fusion::LaserScan> result;
    while (auto s = reader.next()) result.push_back(s->scan);
    return result;
  }();
  return all;
}

std::vector<wm::fusion::RangeReading> readings(const wm::fusion::LaserScan& scan) {
  std::vector<wm::fusion::RangeReading> r;
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double range = scan.ranges_m[i];
    if (std::isfinite(range) && range >= scan.range_min_m && range < scan.range_max_m && range > 0)
      r.push_back({range, scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad});
  }
  return r;
}

// The same without the bend test (ScanLineOptions::split_bends), for its cost.
void extract(benchmark::State& state, bool split_bends) {
  const auto& all = scans();
  std::vector<std::vector<wm::fusion::RangeReading>> prepared;
  for (const auto& s : all) prepared.push_back(readings(s));
  const Eigen::Matrix3d pose_cov = Eigen::Vector3d(9e-4, 9e-4, 7.6e-5).asDiagonal();
  wm::fusion::ScanLineOptions options;
  options.split_bends = split_bends;
  std::size_t i = 0, segments = 0;
  for (auto _ : state) {
    const auto k = i++ % all.size();
    const auto lines = wm::fusion::extract_scan_lines(prepared[k], all[k].sensor_pose, pose_cov, options);
    segments += lines.size();
    benchmark::DoNotOptimize(lines);
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["segments_per_scan"] = static_cast<double>(segments) / static_cast<double>(state.iterations());
}
void BM_ScanLineExtraction(benchmark::State& state) { extract(state, true); }
BENCHMARK(BM_ScanLineExtraction);
void BM_ScanLineExtractionWithoutBendTest(benchmark::State& state) { extract(state, false); }
BENCHMARK(BM_ScanLineExtractionWithoutBendTest);

void BM_BayesGridInsertSameScan(benchmark::State& state) {
  const auto& all = scans();
  wm::fusion::GridOptions options;
  options.update_ds = false;
  wm::fusion::OccupancyGrid grid(options);
  std::size_t i = 0;
  for (auto _ : state) grid.insert(all[i++ % all.size()]);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_BayesGridInsertSameScan);

}  // namespace

int main(int argc, char** argv) {
  return wm::bench::run_with_ratios(
      argc, argv,
      {{"against a Bayes grid insert of the same scan", "BM_BayesGridInsertSameScan"},
       {"against the extraction without the bend test", "BM_ScanLineExtractionWithoutBendTest"}});
}
