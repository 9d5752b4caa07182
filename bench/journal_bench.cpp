// What start-up pays per journaled scan to get it back for the grid: the scan journal's binary record (decode) against
// the JSON request body the journal used to keep (parse with the wire codec, the baseline), for scans of 180, 361
// and 1 081 beams of real-looking ranges. The ratio of the two per size is the figure to report.
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>

#include "logs/scan_body.h"
#include "server/json/codec.h"
#include "server/storage/scan_record.h"

namespace {

wm::world::ScanObservation scan_of(int beams) {
  wm::fusion::LaserScan laser;
  laser.sensor_pose = {12.345678, -3.21, 1.2345};
  laser.angle_min_rad = -M_PI / 2;
  laser.angle_increment_rad = M_PI / (beams - 1);
  laser.range_max_m = 30;
  for (int i = 0; i < beams; ++i) laser.ranges_m.push_back(2.0 + 1.5 * std::sin(0.05 * i) + 0.001 * (i % 7));
  wm::world::ScanObservation scan;
  scan.observer = "robot-1";
  scan.stamp_s = 1700000000.25;
  scan.scan = laser;
  return scan;
}

void BM_JsonBody(benchmark::State& state) {  // the baseline
  const auto scan = scan_of(static_cast<int>(state.range(0)));
  const auto body = wm::logs::laser_scan_body(std::get<wm::fusion::LaserScan>(scan.scan), "robot-1", 1.0).dump();
  const wm::json_codec::ScanLimits limits;
  for (auto _ : state) benchmark::DoNotOptimize(wm::json_codec::parse_scan(body, limits));
  state.counters["bytes"] = static_cast<double>(body.size());
}

void BM_ScanRecord(benchmark::State& state) {
  const auto record = wm::storage::encode_scan(scan_of(static_cast<int>(state.range(0))));
  for (auto _ : state) benchmark::DoNotOptimize(wm::storage::decode_scan(record, "robot-1", 1.0));
  state.counters["bytes"] = static_cast<double>(record.size());
}

BENCHMARK(BM_JsonBody)->Arg(180)->Arg(361)->Arg(1081);
BENCHMARK(BM_ScanRecord)->Arg(180)->Arg(361)->Arg(1081);

}  // namespace

BENCHMARK_MAIN();
