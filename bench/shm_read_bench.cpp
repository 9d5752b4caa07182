// Reading a 1000 × 1000 cell grid layer from a real wmd child process: through shared memory (the header-only reader
// of clients/shm/) against the HTTP ways, in one run:
//  - GET /api/v1/grid?bbox= (JSON, the baseline the issue names; bytes received, not parsed: parsing would only add);
//  - the same with format=pgm (one byte a cell, quantised);
//  - GET /api/v1/grid/tiles/bayes/{tx}/{ty} for every tile (float32, one keep-alive connection);
//  - the shared-memory reader's read_layer into a reused array (every tile under its seqlock into one dense float
//    array, all the tiles the scans touched: more cells than the 1000 × 1000 box, which counts against it).
// The grid: synthetic 360° scans of a 50 m × 50 m room at 0.05 m cells from a 5 × 5 lattice of poses.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <vector>

#include "bench/support/ratio_reporter.h"
#include "bench/support/wmd_child.h"
#include "wire/shm/worldmodel_shm.h"

namespace {

using wm::bench::Connection;
using wm::bench::WmdProcess;
namespace http = boost::beast::http;

constexpr double kRoomM = 50.0;
constexpr double kCellsPerSide = 1000.0;  // 50 m at 0.05 m

// A 360° scan at 0.25° from (x, y) inside the square room [0, 50]², exact ranges to the walls.
std::string room_scan(double x, double y) {
  nlohmann::json ranges = nlohmann::json::array();
  constexpr int kBeams = 1440;
  for (int i = 0; i < kBeams; ++i) {
    const double a = -std::numbers::pi + i * 2 * std::numbers::pi / kBeams;
    const double dx = std::cos(a), dy = std::sin(a);
    double t = 1e9;
    if (dx > 1e-12) t = std::min(t, (kRoomM - x) / dx);
    if (dx < -1e-12) t = std::min(t, -x / dx);
    if (dy > 1e-12) t = std::min(t, (kRoomM - y) / dy);
    if (dy < -1e-12) t = std::min(t, -y / dy);
    ranges.push_back(t);
  }
  return nlohmann::json{{"sensor", "laser"},
                        {"source", "bench"},
                        {"pose", {{"x", x}, {"y", y}, {"theta", 0.0}}},
                        {"angle_min", -std::numbers::pi},
                        {"angle_increment", 2 * std::numbers::pi / kBeams},
                        {"ranges", ranges},
                        {"range_min", 0.05},
                        {"range_max", 80.0},
                        {"sigma_range", 0.01}}
      .dump();
}

// The server with its grid, made once for every benchmark of the run.
struct Fixture {
  WmdProcess wmd{{"--no-scan-lines", "--grid-trim-every", "0", "--usable-range", "80", "--sync", "normal"}};
  std::string segment;
  std::vector<std::pair<std::int64_t, std::int64_t>> tiles;

  Fixture() {
    Connection c(wmd.port());
    for (int i = 0; i < 5; ++i)
      for (int j = 0; j < 5; ++j) {
        const auto answer = c.request(http::verb::post, "/api/v1/scans", room_scan(5.0 + 10 * i, 5.0 + 10 * j));
        if (answer.status != 200) throw std::runtime_error("POST /api/v1/scans: " + answer.body);
      }
    const auto grid_tiles = nlohmann::json::parse(c.request(http::verb::get, "/api/v1/grid/tiles").body);
    for (const auto& t : grid_tiles["tiles"]) tiles.emplace_back(t[0].get<std::int64_t>(), t[1].get<std::int64_t>());
    // Waits for the exporter's pass that holds every scan.
    const auto revision = grid_tiles["revision"].get<std::uint64_t>();
    for (int attempt = 0;; ++attempt) {
      segment = nlohmann::json::parse(c.request(http::verb::get, "/api/v1/shm").body).at("name");
      if (worldmodel::shm::Reader(segment).grid_revision() == revision) break;
      if (attempt > 500) throw std::runtime_error("the shared memory segment did not catch up");
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

void get_bytes(benchmark::State& state, const std::string& target) {
  Connection c(fixture().wmd.port());
  std::size_t bytes = 0;
  for (auto _ : state) {
    auto answer = c.request(http::verb::get, target);
    if (answer.status != 200) state.SkipWithError(answer.body.c_str());
    bytes = answer.body.size();
    benchmark::DoNotOptimize(answer.body.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(kCellsPerSide * kCellsPerSide));
  state.counters["body_MB"] = static_cast<double>(bytes) / 1e6;
}

void BM_GetGridJson(benchmark::State& state) { get_bytes(state, "/api/v1/grid?layer=bayes&bbox=0,0,50,50"); }
void BM_GetGridPgm(benchmark::State& state) { get_bytes(state, "/api/v1/grid?layer=bayes&bbox=0,0,50,50&format=pgm"); }

void BM_GetEveryTile(benchmark::State& state) {
  Connection c(fixture().wmd.port());
  for (auto _ : state) {
    for (const auto& [tx, ty] : fixture().tiles) {
      auto answer =
          c.request(http::verb::get, "/api/v1/grid/tiles/bayes/" + std::to_string(tx) + "/" + std::to_string(ty));
      benchmark::DoNotOptimize(answer.body.data());
    }
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(kCellsPerSide * kCellsPerSide));
  state.counters["tiles"] = static_cast<double>(fixture().tiles.size());
}

void BM_SharedMemoryReadLayer(benchmark::State& state) {
  worldmodel::shm::Reader reader(fixture().segment);
  worldmodel::shm::Reader::Dense dense;  // reused, as a planner polling the grid does
  for (auto _ : state) {
    reader.read_layer(worldmodel::shm::Layer::bayes, dense);
    benchmark::DoNotOptimize(dense.values.data());
  }
  const auto cells = dense.values.size();
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(kCellsPerSide * kCellsPerSide));
  state.counters["cells_read"] = static_cast<double>(cells);
}

}  // namespace

BENCHMARK(BM_GetGridJson)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_GetGridPgm)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_GetEveryTile)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SharedMemoryReadLayer)->Unit(benchmark::kMillisecond)->UseRealTime();

int main(int argc, char** argv) {
  return wm::bench::run_with_ratios(argc, argv, {{"1000 x 1000 grid layer read", "BM_GetGridJson/real_time"}});
}
