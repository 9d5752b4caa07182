// Scans through the running wmd, beyond the grid itself: the processing network (a laser-only task file, the
// shipped default), grid tiles and their tags, concurrent writers, refused scans, sonar cones, live events.
#include <algorithm>
#include <atomic>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include "e2e_fixture.h"
#include "grid_room.h"

namespace wm::testing {
namespace {

using namespace grid_room;

class LaserOnlyNetworkTest : public GridTest {
 protected:
  void SetUp() override {
    extra_args_ = {"--network", std::string(WM_SOURCE_DIR) + "/networks/laser_only.yaml"};
    ServerFixture::SetUp();
  }
};

TEST_F(LaserOnlyNetworkTest, SonarScansAreRefusedAndTheLaserPathWorks) {
  const json sonar = {{"sensor", "sonar"}, {"source", "robot-2"}, {"pose", {{"x", 4}, {"y", 3}, {"theta", 0}}},
                      {"angles", {0.0}},   {"ranges", {2.0}},     {"beam_width", 0.4363},
                      {"range_max", 5.0},  {"sigma_range", 0.02}};
  const auto refused = post_scan(sonar, 422);
  EXPECT_NE(refused["detail"].get<std::string>().find("laser_only.yaml) does not process sonar scans"),
            std::string::npos)
      << refused.dump();
  const auto arc = get_json("/api/v1/grid?bbox=5.95,2.95,6.05,3.05");
  EXPECT_TRUE(arc["data"][0].is_null()) << "the sonar arc is not in the grid";
  const auto first = post_scan(room_scan(3, 3, 0.3));
  EXPECT_EQ(first["grid_revision"], 1) << "the refused sonar scan was not journaled";
  EXPECT_FALSE(first["lines"].is_null());

  // A function's activation is counted when it returns, which may be just after the answer it let go.
  json network;
  for (int attempt = 0; attempt < 100; ++attempt) {
    network = get_json("/api/v1/network");
    const bool all_counted = std::all_of(network["functions"].begin(), network["functions"].end(), [](const json& f) {
      return f["function"] != "laser" || f["activations"].get<int>() >= 1;
    });
    if (all_counted) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_NE(network["source"].get<std::string>().find("laser_only.yaml"), std::string::npos);
  std::set<std::string> functions;
  for (const auto& f : network["functions"])
    functions.insert(f["component"].get<std::string>() + "." + f["function"].get<std::string>());
  EXPECT_TRUE(functions.count("matcher.laser"));
  EXPECT_FALSE(functions.count("matcher.sonar"));
  EXPECT_FALSE(functions.count("grid.laser_and_sonar"));
  for (const auto& f : network["functions"]) {
    if (f["function"] == "laser") {
      EXPECT_EQ(f["activations"], 1) << f.dump();
    }
  }
  std::size_t executors = network["executors"].size();
  EXPECT_EQ(executors, 4u);
}

// GET /api/v1/grid/tiles and /{layer}/{tx}/{ty}: the tiles put back together are the layer GET /api/v1/grid gives,
// and a tile's ETag changes exactly when a scan changed it.
TEST_F(GridTest, TilesReassembleToTheWholeGridAndTheirTagsFollowTheirRevisions) {
  namespace bhttp = boost::beast::http;
  post_scan(room_scan(3, 3, 0.3));
  post_scan(room_scan(5, 3, 1.0));
  const auto whole = get_json("/api/v1/grid?layer=ds_belief");
  const auto index = get_json("/api/v1/grid/tiles");
  const auto size = index["tile_size_cells"].get<std::int64_t>();
  const double resolution = index["resolution"].get<double>();
  EXPECT_EQ(index["revision"], whole["revision"]);
  const auto width = whole["width"].get<std::int64_t>(), height = whole["height"].get<std::int64_t>();
  const auto x0 = std::llround(whole["origin"][0].get<double>() / resolution);
  const auto y0 = std::llround(whole["origin"][1].get<double>() / resolution);
  std::vector<float> assembled(static_cast<std::size_t>(width * height), std::numeric_limits<float>::quiet_NaN());
  std::vector<bool> covered(assembled.size(), false);
  std::map<std::pair<std::int64_t, std::int64_t>, std::string> tags;
  ASSERT_FALSE(index["tiles"].empty());
  for (const auto& t : index["tiles"]) {
    const auto tx = t[0].get<std::int64_t>(), ty = t[1].get<std::int64_t>();
    const auto tile = raw_request(server_->port(), bhttp::verb::get,
                                  "/api/v1/grid/tiles/ds_belief/" + std::to_string(tx) + "/" + std::to_string(ty), {});
    ASSERT_EQ(tile.result_int(), 200) << tile.body();
    EXPECT_EQ(tile[bhttp::field::content_type], "application/octet-stream");
    ASSERT_EQ(tile.body().size(), static_cast<std::size_t>(size * size) * sizeof(float));
    tags[{tx, ty}] = std::string(tile[bhttp::field::etag]);
    std::vector<float> values(static_cast<std::size_t>(size * size));
    std::memcpy(values.data(), tile.body().data(), tile.body().size());
    for (std::int64_t j = 0; j < size; ++j)
      for (std::int64_t i = 0; i < size; ++i) {
        const auto gx = tx * size + i - x0, gy = ty * size + j - y0;
        ASSERT_TRUE(gx >= 0 && gx < width && gy >= 0 && gy < height) << "a tile outside the grid's bounds";
        const auto at = static_cast<std::size_t>(gy * width + gx);
        assembled[at] = values[static_cast<std::size_t>(j * size + i)];
        covered[at] = true;
      }
  }
  std::size_t known = 0;
  for (std::size_t k = 0; k < assembled.size(); ++k) {
    const auto& cell = whole["data"][k];
    // The bounds are a rectangle of tiles; one that no beam reached is not listed, and all unknown.
    if (!covered[k]) {
      EXPECT_TRUE(cell.is_null()) << "cell " << k << " is known but in no listed tile";
      continue;
    }
    if (cell.is_null()) {
      EXPECT_TRUE(std::isnan(assembled[k])) << "cell " << k;
    } else {
      EXPECT_NEAR(assembled[k], cell.get<double>(), 6e-5) << "cell " << k;
      ++known;
    }
  }
  EXPECT_GT(known, 1000u);

  // Unchanged tiles answer 304 to their tag; a scan far from the rooms changes only its own tiles.
  const auto [some, some_tag] = *tags.begin();
  const auto tile_path = [](const std::pair<std::int64_t, std::int64_t>& t) {
    return "/api/v1/grid/tiles/ds_belief/" + std::to_string(t.first) + "/" + std::to_string(t.second);
  };
  EXPECT_EQ(raw_request(server_->port(), bhttp::verb::get, tile_path(some), {{"If-None-Match", some_tag}}).result_int(),
            304);
  post_scan(room_scan(3, 3, 0.3));  // the same room again: every tile it reaches changes
  const auto after = get_json("/api/v1/grid/tiles");
  std::size_t changed = 0, same = 0;
  for (const auto& t : after["tiles"]) {
    const std::pair<std::int64_t, std::int64_t> key{t[0].get<std::int64_t>(), t[1].get<std::int64_t>()};
    if (!tags.count(key)) continue;
    const auto again = raw_request(server_->port(), bhttp::verb::get, tile_path(key), {{"If-None-Match", tags[key]}});
    const bool moved = std::find_if(index["tiles"].begin(), index["tiles"].end(), [&](const json& old) {
                         return old[0] == t[0] && old[1] == t[1] && old[2] != t[2];
                       }) != index["tiles"].end();
    EXPECT_EQ(again.result_int(), moved ? 200 : 304) << t.dump();
    (moved ? changed : same) += 1;
  }
  EXPECT_GT(changed, 0u);

  // Bad tiles: the reason, or 404 for a tile nobody observed.
  EXPECT_EQ(call("GET", "/api/v1/grid/tiles/nope/0/0").status, 400);
  EXPECT_EQ(call("GET", "/api/v1/grid/tiles/bayes/x/0").status, 400);
  EXPECT_EQ(call("GET", "/api/v1/grid/tiles/bayes/0/1e3").status, 400);
  const auto missing = call("GET", "/api/v1/grid/tiles/bayes/100000/0");
  EXPECT_EQ(missing.status, 404);
  EXPECT_NE(missing.body.find("no observed cell"), std::string::npos) << missing.body;
}

TEST_F(GridTest, TheDefaultNetworkIsTheShippedFileAndServesEveryPath) {
  // networks/default.yaml is what --print-network prints, so users start their own from the real thing.
  std::ifstream shipped(std::string(WM_SOURCE_DIR) + "/networks/default.yaml");
  std::stringstream text;
  text << shipped.rdbuf();
  const auto printed = run_command(std::string(WM_WMD_PATH) + " --print-network");
  EXPECT_EQ(printed.status, 0);
  EXPECT_EQ(printed.output, text.str());
  post_scan(room_scan(3, 3, 0.3));
  const auto network = get_json("/api/v1/network");
  EXPECT_EQ(network["source"], "<default network>");
  bool committed = false;
  for (const auto& f : network["functions"])
    if (f["component"] == "store" && f["function"] == "commit") committed = f["activations"].get<int>() >= 1;
  EXPECT_TRUE(committed) << network.dump();
  std::size_t depth = 0;
  for (const auto& p : network["ports"]) depth += p["depth"].get<std::size_t>();
  EXPECT_EQ(depth, 0u) << "the scan was answered after every stage";
}

// Requests that change nothing (a sonar scan) stay in flight while others are decided after them: those must be
// decided against the map as it is, plan and all (a stale head once dropped the plan loaded before).
TEST_F(GridTest, ConcurrentSonarScansAndPrimitivesAfterAPlanKeepThePlan) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  const auto objects = get_json("/api/v1/map")["objects"].size();
  ASSERT_GT(objects, 0u);
  const json sonar = {{"sensor", "sonar"}, {"source", "robot-2"}, {"pose", {{"x", 4}, {"y", 3}, {"theta", 0}}},
                      {"angles", {0.0}},   {"ranges", {2.0}},     {"beam_width", 0.4363},
                      {"range_max", 5.0},  {"sigma_range", 0.02}};
  std::atomic<int> failures{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < 4; ++c)
    clients.emplace_back([&, c] {
      client::HttpClient http(server_->url());
      for (int i = 0; i < 25; ++i) {
        json body = sonar;
        std::string target = "/api/v1/scans";
        if (c % 2 == 1) {
          target = "/api/v1/primitives";
          const double y = 0.5 + 0.37 * i + 0.05 * c;
          body = {{"source", "robot-" + std::to_string(c)}, {"segments", {{{"p0", {20, y}}, {"p1", {21, y}}}}}};
        }
        const auto r = http.request("POST", target, body.dump());
        if (r.status != 200) {
          ++failures;
          ADD_FAILURE() << target << " " << r.status << ": " << r.body;
        }
      }
    });
  for (auto& t : clients) t.join();
  EXPECT_EQ(failures, 0);
  const auto map = get_json("/api/v1/map");
  EXPECT_EQ(map["objects"].size(), objects) << "the plan is still there";
  EXPECT_EQ(get_json("/api/v1/health")["last_decision_seq"].get<int>(), 50) << "every primitive decided once";
}

TEST_F(GridTest, BadScansAreRefusedAndChangeNothing) {
  post_scan(room_scan(3, 3, 0.0));
  const auto before = get_raw("/api/v1/grid/map.pgm");
  auto scan = room_scan(3, 3, 0.0);
  std::vector<std::pair<std::string, json>> bad;
  auto with = [&](const std::string& key, const json& value) {
    auto s = scan;
    s[key] = value;
    return s;
  };
  bad.push_back({"range_max", with("range_max", -1)});
  bad.push_back({"sensor", with("sensor", "radar")});
  bad.push_back({"pose", with("pose", json{{"x", 1}, {"y", 2}})});
  bad.push_back({"ranges", with("ranges", json::array())});
  bad.push_back({"ranges[2]", with("ranges", json::array({1.0, 2.0, "x"}))});
  bad.push_back({"angle_increment", with("angle_increment", 0)});
  bad.push_back({"colour", with("colour", "red")});
  auto sonar = scan;
  sonar["sensor"] = "sonar";
  bad.push_back({"unknown field for a sonar scan", sonar});  // a sonar ring has angles, not angle_min
  for (const auto& [field, body] : bad) {
    const auto r = send_json("POST", "/api/v1/scans", body, 400);
    EXPECT_NE(r["detail"].get<std::string>().find(field), std::string::npos) << field << ": " << r.dump();
  }
  EXPECT_EQ(get_raw("/api/v1/grid/map.pgm"), before);
  // Invalid beams are ignored one by one, not the scan: null (no reading) and a negative range.
  auto partial = room_scan(3, 3, 0.0);
  partial["ranges"][10] = nullptr;
  partial["ranges"][11] = -1.0;
  EXPECT_EQ(send_json("POST", "/api/v1/scans", partial)["grid_revision"], 2);
}

TEST_F(GridTest, ASonarConeMarksItsArcAndFreesInside) {
  json sonar = {{"sensor", "sonar"}, {"source", "robot-2"}, {"pose", {{"x", 4}, {"y", 3}, {"theta", 0}}},
                {"angles", {0.0}},   {"ranges", {2.0}},     {"beam_width", 0.4363},
                {"range_max", 5.0},  {"sigma_range", 0.02}};
  for (int i = 0; i < 5; ++i) post_scan(sonar);
  // The arc at 2 m, ±12.5°, is occupied; the cone at 1 m is free.
  const auto arc = get_json("/api/v1/grid?bbox=5.95,2.95,6.05,3.05");
  EXPECT_GT(arc["data"][0].get<double>(), 0.65);
  const auto side = get_json("/api/v1/grid?bbox=5.93,3.35,5.97,3.39");  // ~10.5° off axis, on the arc
  EXPECT_GT(side["data"][0].get<double>(), 0.5);
  const auto inside = get_json("/api/v1/grid?bbox=5.0,2.95,5.05,3.0");
  EXPECT_LT(inside["data"][0].get<double>(), 0.5);
  EXPECT_TRUE(get_json("/api/v1/grid?bbox=5.0,4.4,5.05,4.45")["data"][0].is_null()) << "outside the cone";
}

// --- live events over the WebSocket ------------------------------------------------------------------

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;

TEST_F(GridTest, EventsArriveInOrderAndASlowClientDoesNotBlockIngest) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  EventClient client(server_->port());
  EXPECT_EQ(client.next()["type"], "hello");
  EventClient stalled(server_->port());  // connects and never reads again

  send_json("POST", "/api/v1/primitives", json::parse(R"({"segments": [{"p0": [3, 10.004], "p1": [7, 9.998]},
                                                                          {"p0": [10, 3], "p1": [13, 3]}]})"));
  const auto update = client.next();
  EXPECT_EQ(update["type"], "update");
  ASSERT_EQ(update["decisions"].size(), 2u);
  EXPECT_EQ(update["decisions"][0]["rule"], "solid_confirmed");
  EXPECT_EQ(update["decisions"][1]["action"], "add");
  EXPECT_EQ(update["elements"][0]["id"], "e1");
  EXPECT_EQ(update["objects"][0]["id"], "wall-n");

  post_scan(room_scan(3, 3, 0.0));
  std::uint64_t last_seq = update["seq"];
  bool saw_scan = false;
  for (int i = 0; i < 6 && !saw_scan; ++i) {  // before it: a robot heard from, the scan lines' update
    const auto e = client.next();
    EXPECT_GT(e["seq"].get<std::uint64_t>(), last_seq);
    last_seq = e["seq"];
    if (e["type"] == "scan") {
      saw_scan = true;
      EXPECT_EQ(e["observer"], "robot-1");
      EXPECT_GT(e["points"].size(), 300u);
    }
  }
  EXPECT_TRUE(saw_scan);

  // Far more events than the per-client queue holds, while `stalled` reads nothing: every request is
  // still answered promptly.
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 60; ++i) post_scan(room_scan(3 + 0.01 * i, 3, 0.0));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 60.0);
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
}

}  // namespace
}  // namespace wm::testing
