// The shared-memory export of a running wmd read by the shipped readers (C++ header, Python module, wmctl shm)
// while real laser logs are replayed, against what GET answers; and what /dev/shm holds after stops and crashes.
#include <signal.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <future>
#include <optional>
#include <thread>

#include "e2e_fixture.h"
#include "wire/shm/worldmodel_shm.h"

namespace wm::testing {
namespace {

namespace shm = worldmodel::shm;
using namespace std::chrono_literals;

bool in_dev_shm(const std::string& name) { return std::filesystem::exists("/dev/shm/" + name); }

// A tile's revision from its ETag ("<run>-r<revision>").
std::uint64_t etag_revision(const std::string& etag) { return std::stoull(etag.substr(etag.rfind("-r") + 2)); }

class ShmTest : public ServerFixture {
 protected:
  std::string segment_name() { return get_json("/api/v1/shm").at("name").get<std::string>(); }

  // The live segment, as a reader finds it: the name GET gives, asked again when the segment grew (and its name
  // was unlinked) between the answer and the open.
  shm::Reader open_live() {
    for (int attempt = 0;; ++attempt) {
      try {
        shm::Reader reader(segment_name());
        if (!reader.successor()) return reader;
      } catch (const shm::Error&) {
        if (attempt >= 20) throw;
      }
    }
  }

  // Waits until the segment holds every scan GET /api/v1/grid counts (the exporter runs every 20 ms).
  shm::Reader caught_up(std::int64_t revision) {
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    for (;;) {
      auto reader = open_live();
      if (static_cast<std::int64_t>(reader.grid_revision()) == revision) return reader;
      if (std::chrono::steady_clock::now() > deadline) {
        ADD_FAILURE() << "the segment stayed at revision " << reader.grid_revision() << ", GET says " << revision;
        return reader;
      }
      std::this_thread::sleep_for(20ms);
    }
  }

  // Replays `log` with wmctl in the background while tiles are read from shared memory and over HTTP: where both
  // name the same tile revision, the four layers must be the same bits. Then, ingest over, the whole Bayes layer
  // must be GET /api/v1/grid's.
  void check_during_ingest(const std::filesystem::path& log, std::size_t limit) {
    auto replay = std::async(std::launch::async, [&] {
      return run_command(wmctl(server_->url(), "--json replay " + log.string() + " --limit " + std::to_string(limit)));
    });
    std::size_t same_revision = 0, compared_reads = 0, torn_or_different = 0;
    std::vector<float> layers;
    while (replay.wait_for(0ms) != std::future_status::ready) {
      auto reader = open_live();
      const auto t = static_cast<std::size_t>(reader.tile_size_cells());
      layers.resize(shm::kLayerCount * t * t);
      for (std::size_t slot = 0; slot < reader.tile_count() && slot < 24; ++slot) {
        const auto key = reader.tile_key(slot);
        const auto tile =
            call("GET", "/api/v1/grid/tiles/bayes/" + std::to_string(key.tx) + "/" + std::to_string(key.ty));
        ASSERT_EQ(tile.status, 200) << tile.body;
        const auto revision = reader.read_tile_layers(slot, layers.data());
        ++compared_reads;
        if (revision != etag_revision(tile.etag)) continue;  // a scan came between the two reads
        ++same_revision;
        if (std::memcmp(layers.data(), tile.body.data(), t * t * sizeof(float)) != 0) ++torn_or_different;
      }
    }
    const auto result = replay.get();
    ASSERT_EQ(result.status, 0) << result.output;
    std::cout << "[shm] " << log.filename().string() << ": " << compared_reads << " tile reads during ingest, "
              << same_revision << " at the revision GET answered, " << torn_or_different << " different\n";
    EXPECT_EQ(torn_or_different, 0u) << "of " << same_revision << " tiles read at the same revision";
    EXPECT_GT(same_revision, 20u) << "of " << compared_reads << " reads during ingest";

    const auto grid = get_json("/api/v1/grid");
    auto reader = caught_up(grid.at("revision").get<std::int64_t>());
    const auto dense = reader.read_layer(shm::Layer::bayes);
    const double resolution = grid.at("resolution").get<double>();
    EXPECT_EQ(dense.width, grid.at("width").get<std::int64_t>());
    EXPECT_EQ(dense.height, grid.at("height").get<std::int64_t>());
    EXPECT_NEAR(static_cast<double>(dense.x0_cells) * resolution, grid.at("origin")[0].get<double>(), 1e-9);
    EXPECT_NEAR(static_cast<double>(dense.y0_cells) * resolution, grid.at("origin")[1].get<double>(), 1e-9);
    const auto& cells = grid.at("data");
    ASSERT_EQ(cells.size(), dense.values.size());
    std::size_t known = 0, differ = 0;
    for (std::size_t i = 0; i < cells.size(); ++i) {
      if (cells[i].is_null() != std::isnan(dense.values[i])) {
        ++differ;
        continue;
      }
      if (cells[i].is_null()) continue;
      ++known;
      differ += std::abs(cells[i].get<double>() - dense.values[i]) > 5.01e-5 ? 1 : 0;  // JSON keeps 4 decimals
    }
    EXPECT_EQ(differ, 0u) << "of " << cells.size() << " cells";
    EXPECT_GT(known, 10'000u);
  }
};

TEST_F(ShmTest, TheSegmentSeesWhatGetSeesWhileTheIntelLogIsReplayed) {
  check_during_ingest(real_data("carmen/intel-corrected.log.gz", "carmen/intel-corrected.log.gz"), 400);
}

TEST_F(ShmTest, TheSegmentSeesWhatGetSeesWhileTheFreiburg079LogIsReplayed) {
  check_during_ingest(real_data("carmen/freiburg-079-corrected.log.gz", "carmen/freiburg-079-corrected-excerpt.log"),
                      400);
}

TEST_F(ShmTest, WmctlAndThePythonReaderAgreeWithTheServer) {
  const auto log = real_data("carmen/intel-corrected.log.gz", "carmen/intel-corrected.log.gz");
  ASSERT_EQ(run_command(wmctl(server_->url(), "replay " + log.string() + " --limit 150")).status, 0);
  const auto revision = get_json("/api/v1/grid").at("revision").get<std::int64_t>();
  auto reader = caught_up(revision);
  const auto check = run_command(wmctl(server_->url(), "shm"));
  EXPECT_EQ(check.status, 0) << check.output;
  EXPECT_NE(check.output.find("ok\n"), std::string::npos) << check.output;
  EXPECT_NE(check.output.find("tiles equal bit for bit"), std::string::npos) << check.output;

  const auto dense = reader.read_layer(shm::Layer::bayes);
  std::size_t known = 0;
  double sum = 0;
  for (const float v : dense.values)
    if (!std::isnan(v)) ++known, sum += v;
  const auto map = reader.read_map();
  const auto http_map = get_json("/api/v1/map");
  EXPECT_EQ(map.version, http_map.at("version").get<std::int64_t>());
  EXPECT_EQ(map.elements.size(), http_map.at("elements").size());

  // The same numbers from Python, with numpy and without.
  const std::string script =
      "import json, math, sys; sys.path.insert(0, '" WM_SOURCE_DIR
      "/clients/shm/python'); import worldmodel_shm as w; "
      "r = w.from_server('" +
      server_->url() +
      "'); d = r.read_layer('bayes'); vals = [float(v) for v in d.values if not math.isnan(v)]; "
      "print(json.dumps({'width': d.width, 'height': d.height, 'x0': d.x0_cells, 'y0': d.y0_cells, "
      "'known': len(vals), 'sum': sum(vals), 'map_version': r.read_map().version, "
      "'elements': len(r.read_map().elements)}))";
  for (const std::string env : {"", "WM_SHM_NO_NUMPY=1 "}) {
    const auto python = run_command(env + "/usr/bin/python3 -c \"" + script + "\"");
    ASSERT_EQ(python.status, 0) << env << python.output;
    const auto answer = json::parse(python.output);
    EXPECT_EQ(answer["width"], dense.width) << env;
    EXPECT_EQ(answer["height"], dense.height) << env;
    EXPECT_EQ(answer["x0"], dense.x0_cells) << env;
    EXPECT_EQ(answer["y0"], dense.y0_cells) << env;
    EXPECT_EQ(answer["known"], known) << env;
    EXPECT_NEAR(answer["sum"].get<double>(), sum, 1e-6 * sum) << env;
    EXPECT_EQ(answer["map_version"], map.version) << env;
    EXPECT_EQ(answer["elements"], map.elements.size()) << env;
  }
}

TEST_F(ShmTest, NothingIsLeftInDevShmAfterACleanStopOrAKillAndARestart) {
  const auto first = segment_name();
  EXPECT_TRUE(in_dev_shm(first));
  shm::Reader mapped(first);
  ASSERT_EQ(server_->stop(), 0) << server_->output();
  EXPECT_FALSE(in_dev_shm(first)) << "a clean stop removes the segment";
  EXPECT_EQ(mapped.state(), shm::SegmentState::stopped);

  start();
  const auto second = segment_name();
  EXPECT_NE(second, first);
  server_->crash();  // kill -9: nothing runs to remove it (another test's wmd starting now may, as the next one does)
  start();
  EXPECT_FALSE(in_dev_shm(second)) << "the next start removes what the killed server left";
  const auto third = segment_name();
  EXPECT_TRUE(in_dev_shm(third));
  ASSERT_EQ(server_->stop(), 0);
  EXPECT_FALSE(in_dev_shm(third));
}

// Each map has a segment of its own, found through its own route, holding that map only; a deleted map's goes.
TEST_F(ShmTest, EachMapHasASegmentOfItsOwnThatGoesWithIt) {
  send_json("POST", "/api/v1/maps", {{"id", "floor2"}}, 201);
  const auto log = real_data("carmen/intel-corrected.log.gz", "carmen/intel-corrected.log.gz");
  ASSERT_EQ(run_command(wmctl(server_->url(), "--map floor2 replay " + log.string() + " --limit 150")).status, 0);
  const auto floor2_name = get_json("/api/v1/maps/floor2/shm").at("name").get<std::string>();
  const auto default_name = segment_name();
  EXPECT_NE(floor2_name, default_name);
  EXPECT_TRUE(in_dev_shm(floor2_name));

  const auto revision = get_json("/api/v1/maps/floor2/grid").at("revision").get<std::int64_t>();
  ASSERT_GT(revision, 0);
  std::optional<shm::Reader> floor2;
  for (int i = 0; i < 500; ++i) {
    floor2.emplace(get_json("/api/v1/maps/floor2/shm").at("name").get<std::string>());
    if (static_cast<std::int64_t>(floor2->grid_revision()) == revision && floor2->read_map().version >= 0) break;
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_EQ(static_cast<std::int64_t>(floor2->grid_revision()), revision);
  const auto http_map = get_json("/api/v1/maps/floor2/map");
  EXPECT_EQ(floor2->read_map().version, http_map.at("version").get<std::int64_t>());
  EXPECT_EQ(floor2->read_map().elements.size(), http_map.at("elements").size());
  EXPECT_GT(http_map.at("elements").size(), 0u);
  // The default map's segment holds the default map: nothing was posted to it.
  shm::Reader main_segment(default_name);
  EXPECT_EQ(main_segment.grid_revision(), 0u);
  EXPECT_EQ(main_segment.read_map().elements.size(), 0u);
  // wmctl on the map compares that map's tiles with its segment.
  const auto check = run_command(wmctl(server_->url(), "--map floor2 shm"));
  EXPECT_EQ(check.status, 0) << check.output;
  EXPECT_NE(check.output.find("tiles equal bit for bit"), std::string::npos) << check.output;

  EXPECT_EQ(send_json("DELETE", "/api/v1/maps/floor2", json(nullptr))["deleted"], "floor2");
  EXPECT_FALSE(in_dev_shm(floor2_name)) << "a deleted map's segment goes with it";
  EXPECT_EQ(floor2->state(), shm::SegmentState::stopped);
  EXPECT_TRUE(in_dev_shm(default_name));
  EXPECT_EQ(call("GET", "/api/v1/maps/floor2/shm").status, 404);
}

class NoShmTest : public ServerFixture {
 protected:
  void SetUp() override {
    extra_args_ = {"--no-shm"};
    ServerFixture::SetUp();
  }
};

TEST_F(NoShmTest, TheRouteSaysSharedMemoryIsOff) {
  const auto answer = call("GET", "/api/v1/shm");
  EXPECT_EQ(answer.status, 404);
  EXPECT_EQ(json::parse(answer.body).at("error"), "shm_disabled");
}

}  // namespace
}  // namespace wm::testing
