// What wmd pays to read a POST /api/v1/scans body into a validated scan: JSON text (the baseline), the CBOR of the
// same document (ranges as an array of float64), and CBOR with the ranges as a float32 typed array (RFC 8746 tag 85),
// for laser scans of 180 and 1 081 beams. Ratios are items/s against JSON of the same size, in the same run.
#include <benchmark/benchmark.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "bench/support/ratio_reporter.h"
#include "logs/scan_body.h"
#include "server/json/codec.h"

namespace {

using nlohmann::json;
using wm::json_codec::BodyFormat;

json scan_document(int beams) {
  wm::fusion::LaserScan laser;
  laser.sensor_pose = {12.345678, -3.21, 1.2345};
  laser.angle_min_rad = -M_PI * 0.75;
  laser.angle_increment_rad = 1.5 * M_PI / (beams - 1);
  laser.range_max_m = 30;
  for (int i = 0; i < beams; ++i) laser.ranges_m.push_back(2.0 + 1.5 * std::sin(0.05 * i) + 0.001 * (i % 7));
  return wm::logs::laser_scan_body(laser, "robot-1", 1700000000.25);
}

std::string body_of(int beams, const std::string& form) {
  auto doc = scan_document(beams);
  if (form == "json") return doc.dump();
  if (form == "cbor_float32") {
    std::vector<std::uint8_t> bytes;
    for (const auto& r : doc["ranges"]) {
      const auto bits = std::bit_cast<std::uint32_t>(r.get<float>());
      for (int k = 0; k < 4; ++k) bytes.push_back(static_cast<std::uint8_t>(bits >> (8 * k)));
    }
    doc["ranges"] = json::binary_t(bytes, wm::json_codec::kCborFloat32LeTag);
  }
  const auto cbor = json::to_cbor(doc);
  return {cbor.begin(), cbor.end()};
}

void bm_parse(benchmark::State& state, int beams, std::string form) {
  const auto body = body_of(beams, form);
  const auto format = form == "json" ? BodyFormat::json : BodyFormat::cbor;
  const wm::json_codec::ScanLimits limits;
  for (auto _ : state) benchmark::DoNotOptimize(wm::json_codec::parse_scan_body(body, format, limits));
  state.SetItemsProcessed(state.iterations());
  state.counters["bytes"] = static_cast<double>(body.size());
}

}  // namespace

int main(int argc, char** argv) {
  for (const int beams : {180, 1081})
    for (const char* form : {"json", "cbor", "cbor_float32"})
      benchmark::RegisterBenchmark((std::string(form) + "/" + std::to_string(beams)).c_str(), bm_parse, beams,
                                   std::string(form))
          ->Unit(benchmark::kMicrosecond);
  return wm::bench::run_with_ratios(argc, argv,
                                    {{"vs JSON (180 beams)", "json/180"}, {"vs JSON (1081 beams)", "json/1081"}});
}
