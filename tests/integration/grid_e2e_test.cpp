// Scans through the running wmd: both grids, the map_server export, persistence, scan lines, live events.
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

namespace wm::testing {
namespace {

struct Wall {
  double ax, ay, bx, by;
};

// The room of these tests: 8 m × 6 m.
const std::vector<Wall> kRoom = {{0, 0, 8, 0}, {8, 0, 8, 6}, {8, 6, 0, 6}, {0, 6, 0, 0}};

std::optional<double> cast(double px, double py, double angle) {
  std::optional<double> best;
  const double dx = std::cos(angle), dy = std::sin(angle);
  for (const auto& w : kRoom) {
    const double ex = w.bx - w.ax, ey = w.by - w.ay;
    const double den = dx * ey - dy * ex;
    if (std::abs(den) < 1e-12) continue;
    const double apx = w.ax - px, apy = w.ay - py;
    const double t = (apx * ey - apy * ex) / den, u = (apx * dy - apy * dx) / den;
    if (t > 1e-9 && u >= 0 && u <= 1 && (!best || t < *best)) best = t;
  }
  return best;
}

// A 360° laser scan at 0.5° from (x, y), exact ranges.
json room_scan(double x, double y, double theta) {
  json ranges = json::array();
  for (int i = 0; i < 720; ++i) ranges.push_back(*cast(x, y, theta - std::numbers::pi + i * std::numbers::pi / 360));
  return {{"sensor", "laser"},
          {"source", "robot-1"},
          {"pose", {{"x", x}, {"y", y}, {"theta", theta}}},
          {"angle_min", -std::numbers::pi},
          {"angle_increment", std::numbers::pi / 360},
          {"ranges", ranges},
          {"range_min", 0.05},
          {"range_max", 20.0},
          {"sigma_range", 0.01}};
}

struct Pgm {
  int width = 0, height = 0;
  std::string pixels;
};

Pgm parse_pgm(const std::string& data) {
  std::istringstream in(data);
  std::string magic;
  in >> magic;
  EXPECT_EQ(magic, "P5");
  auto next_number = [&] {
    in >> std::ws;
    while (in.peek() == '#') {
      std::string comment;
      std::getline(in, comment);
      in >> std::ws;
    }
    int v = 0;
    in >> v;
    return v;
  };
  Pgm pgm;
  pgm.width = next_number();
  pgm.height = next_number();
  EXPECT_EQ(next_number(), 255);
  in.get();  // the single whitespace before the raster
  pgm.pixels.assign(std::istreambuf_iterator<char>(in), {});
  EXPECT_EQ(pgm.pixels.size(), static_cast<std::size_t>(pgm.width * pgm.height));
  return pgm;
}

// A map_server reading of the YAML keys this test needs.
std::map<std::string, std::string> parse_yaml(const std::string& text) {
  std::map<std::string, std::string> keys;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    const auto colon = line.find(':');
    if (colon != std::string::npos) keys[line.substr(0, colon)] = line.substr(line.find_first_not_of(' ', colon + 1));
  }
  return keys;
}

class GridTest : public ServerFixture {
 protected:
  void SetUp() override {
    extra_args_ = {"--grid-flush-ms", "3600000"};  // only journal + replay keep scans across a crash
    ServerFixture::SetUp();
  }
  json post_scan(const json& scan, int status = 200) { return send_json("POST", "/api/v1/scans", scan, status); }
  std::string get_raw(const std::string& target) {
    const auto r = call("GET", target);
    EXPECT_EQ(r.status, 200) << r.body.substr(0, 300);
    return r.body;
  }
};

TEST_F(GridTest, ScansOfARoomGiveWallsOccupiedAndTheInsideFree) {
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{3, 3}, {5, 2}, {2, 4.5}, {6.5, 4}, {4, 1.5}})
    post_scan(room_scan(x, y, 0.3));
  const auto grid = get_json("/api/v1/grid?layer=bayes&bbox=-0.5,-0.5,8.5,6.5");
  const double res = grid["resolution"];
  const double ox = grid["origin"][0], oy = grid["origin"][1];
  const int width = grid["width"], height = grid["height"];
  ASSERT_EQ(grid["data"].size(), static_cast<std::size_t>(width * height));
  auto value = [&](double x, double y) -> std::optional<double> {
    const int cx = static_cast<int>(std::floor((x - ox) / res)), cy = static_cast<int>(std::floor((y - oy) / res));
    const auto& v = grid["data"][cy * width + cx];
    return v.is_null() ? std::nullopt : std::optional<double>(v.get<double>());
  };
  // Within one cell of each wall point an occupied cell; the room's inside free.
  int walls_ok = 0, wall_points = 0;
  for (double t = 0.5; t < 7.5; t += 0.25) {
    for (const auto& [x, y] : std::vector<std::pair<double, double>>{{t, 0.0}, {t, 6.0}}) {
      ++wall_points;
      bool occupied = false;
      for (double dx = -res; dx <= res; dx += res)
        for (double dy = -res; dy <= res; dy += res) occupied = occupied || value(x + dx, y + dy).value_or(0) > 0.65;
      walls_ok += occupied;
    }
  }
  EXPECT_EQ(walls_ok, wall_points);
  int free_ok = 0, inside = 0;
  for (double x = 1.0; x < 7.0; x += 0.5)
    for (double y = 1.0; y < 5.0; y += 0.5) {
      ++inside;
      free_ok += value(x, y).value_or(1.0) < 0.196;
    }
  EXPECT_EQ(free_ok, inside);
  EXPECT_FALSE(value(-0.4, -0.4).has_value()) << "outside the room nothing was seen";

  // The Dempster–Shafer layers agree on the walls and keep their own meaning.
  // (A column of three cells across the wall y = 6 at x = 3.)
  const auto belief = get_json("/api/v1/grid?layer=ds_belief&bbox=2.95,5.95,3.0,6.1");
  const auto plausibility = get_json("/api/v1/grid?layer=ds_plausibility&bbox=2.95,5.95,3.0,6.1");
  ASSERT_EQ(belief["data"].size(), 3u);
  double best = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    if (belief["data"][i].is_null()) continue;
    best = std::max(best, belief["data"][i].get<double>());
    EXPECT_GE(plausibility["data"][i].get<double>(), belief["data"][i].get<double>());
  }
  EXPECT_GT(best, 0.5);
  EXPECT_EQ(call("GET", "/api/v1/grid?layer=nope").status, 400);
  EXPECT_EQ(call("GET", "/api/v1/grid?bbox=1,2,3").status, 400);
}

TEST_F(GridTest, TheMapServerPairDescribesTheSameRaster) {
  post_scan(room_scan(3, 3, 0.0));
  post_scan(room_scan(5, 3, 1.0));
  const auto yaml = parse_yaml(get_raw("/api/v1/grid/map.yaml"));
  EXPECT_EQ(yaml.at("image"), "map.pgm");
  EXPECT_EQ(yaml.at("negate"), "0");
  EXPECT_EQ(std::stod(yaml.at("occupied_thresh")), 0.65);
  EXPECT_EQ(std::stod(yaml.at("free_thresh")), 0.196);
  const double res = std::stod(yaml.at("resolution"));
  double ox = 0, oy = 0;
  ASSERT_EQ(std::sscanf(yaml.at("origin").c_str(), "[%lf, %lf", &ox, &oy), 2);
  const auto pgm = parse_pgm(get_raw("/api/v1/grid/map.pgm"));
  // map_server: occupancy = (255 - pixel) / 255; rows from the top. The wall y = 6 at x = 3 is occupied,
  // the room centre free, far outside unknown.
  auto occupancy = [&](double x, double y) {
    const int col = static_cast<int>(std::floor((x - ox) / res));
    const int row = pgm.height - 1 - static_cast<int>(std::floor((y - oy) / res));
    return (255.0 - static_cast<unsigned char>(pgm.pixels[static_cast<std::size_t>(row * pgm.width + col)])) / 255.0;
  };
  EXPECT_GT(std::max({occupancy(3.0, 6.0), occupancy(3.0, 5.99), occupancy(3.0, 6.04)}), 0.65);
  EXPECT_LT(occupancy(4.0, 3.0), 0.196 + 0.25) << "one or two misses: free or nearly";
  const double unknown = occupancy(ox + 0.01, oy + 0.01);
  EXPECT_GT(unknown, 0.196);
  EXPECT_LT(unknown, 0.65);
}

TEST_F(GridTest, TheGridSurvivesACrashAndARestartExactly) {
  post_scan(room_scan(3, 3, 0.0));
  post_scan(room_scan(5, 2, 0.5));
  const auto before = get_raw("/api/v1/grid?layer=ds_conflict&bbox=-1,-1,9,7");
  const auto bayes_before = get_raw("/api/v1/grid/map.pgm");
  server_->crash();  // no flush: the tiles come back from the journal
  start();
  EXPECT_EQ(json::parse(get_raw("/api/v1/grid?layer=ds_conflict&bbox=-1,-1,9,7"))["data"], json::parse(before)["data"]);
  EXPECT_EQ(get_raw("/api/v1/grid/map.pgm"), bayes_before);
  restart();  // a clean stop flushes the tiles; the journal is not needed then
  EXPECT_EQ(get_raw("/api/v1/grid/map.pgm"), bayes_before);
}

TEST_F(GridTest, LaserScansAlsoFeedTheVectorMapThroughTheRules) {
  const auto answer = post_scan(room_scan(3, 3, 0.0));
  ASSERT_FALSE(answer["lines"].is_null());
  const auto& decisions = answer["lines"]["decisions"];
  // Four walls; the one behind the robot is cut where the 360° scan wraps, and its second half is merged
  // into the first by the rules within the same request.
  ASSERT_GE(decisions.size(), 4u) << decisions.dump();
  int adds = 0;
  for (const auto& d : decisions) {
    EXPECT_EQ(d["origin"], "scan");
    EXPECT_EQ(d["sensor"], "laser");
    adds += d["action"] == "add";
  }
  EXPECT_EQ(adds, 4);
  const auto second = post_scan(room_scan(4, 2.5, 0.7));
  for (const auto& d : second["lines"]["decisions"]) EXPECT_EQ(d["action"], "merge") << d.dump();
  const auto map = get_json("/api/v1/map");
  EXPECT_EQ(map["elements"].size(), 4u);
  for (const auto& e : map["elements"]) EXPECT_EQ(e["source"], "scan");
}

// Distance [m] from a wall's midpoint to a map element's line, and the angle between them [rad].
std::pair<double, double> element_to_wall(const json& element, const Wall& w) {
  const double rho = element["rho"], phi = element["phi"];
  const double mx = 0.5 * (w.ax + w.bx), my = 0.5 * (w.ay + w.by);
  const double offset = std::abs(mx * std::cos(phi) + my * std::sin(phi) - rho);
  const double wall_normal = std::atan2(w.bx - w.ax, -(w.by - w.ay));
  double dphi = std::remainder(phi - wall_normal, std::numbers::pi);
  return {offset, std::abs(dphi)};
}

TEST_F(GridTest, GridLinesAreExtractedOnDemandAndDecidedLikeOtherPrimitives) {
  // Nothing mapped yet: nothing to extract, and nothing changes.
  const auto empty = send_json("POST", "/api/v1/grid/extract", json::object());
  EXPECT_EQ(empty["segments"], 0);
  EXPECT_TRUE(empty["observation"].is_null());

  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{3, 3}, {5, 2}, {2, 4.5}, {6.5, 4}, {4, 1.5}})
    post_scan(room_scan(x, y, 0.3));
  const auto scanned = get_json("/api/v1/map");
  ASSERT_EQ(scanned["elements"].size(), 4u) << scanned.dump();

  const auto answer = send_json("POST", "/api/v1/grid/extract", json::object());
  ASSERT_GE(answer["segments"].get<int>(), 4) << answer.dump();
  ASSERT_FALSE(answer["observation"].is_null());
  // One decision per segment; besides them only cuts of element ends that ran past a wall the grid saw.
  std::size_t per_segment = 0;
  int merges = 0;
  for (const auto& d : answer["decisions"]) {
    EXPECT_EQ(d["origin"], "grid") << d.dump();
    EXPECT_EQ(d["sensor"], "grid") << d.dump();
    if (d["index"].get<int>() < 0) {
      EXPECT_EQ(d["rule"], "grid_crossing_trimmed") << d.dump();
      continue;
    }
    ++per_segment;
    merges += d["action"] == "merge";
  }
  EXPECT_EQ(per_segment, answer["segments"].get<std::size_t>());
  // The grid's walls are the walls the scans already mapped: each of the four is confirmed, none is added twice.
  EXPECT_GE(merges, 4) << answer.dump();
  const auto map = get_json("/api/v1/map");
  ASSERT_EQ(map["elements"].size(), 4u) << map.dump();
  for (const Wall& w : kRoom) {
    bool found = false;
    for (const auto& e : map["elements"]) {
      const auto [offset, dphi] = element_to_wall(e, w);
      found = found || (offset < 0.03 && dphi < 0.5 * std::numbers::pi / 180);
    }
    EXPECT_TRUE(found) << "wall (" << w.ax << ", " << w.ay << ") - (" << w.bx << ", " << w.by << ")\n" << map.dump();
  }
  // The log says where each decision came from.
  const auto log = get_json("/api/v1/decisions?since=" + std::to_string(answer["observation"].get<long>() - 1));
  std::size_t from_grid = 0;
  for (const auto& d : log["decisions"]) from_grid += d["origin"] == "grid";
  EXPECT_EQ(from_grid, answer["decisions"].size());
}

TEST_F(GridTest, WmctlRunsTheExtractor) {
  const auto wmctl = std::string(WM_WMCTL_PATH) + " --server " + server_->url();
  auto r = run_command(wmctl + " grid extract");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("no lines in the grid"), std::string::npos) << r.output;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{3, 3}, {5, 2}, {2, 4.5}, {6.5, 4}, {4, 1.5}})
    post_scan(room_scan(x, y, 0.3));
  r = run_command(wmctl + " --json grid extract");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto answer = json::parse(r.output);
  EXPECT_GE(answer["segments"].get<int>(), 4) << r.output;
}

class GridEveryTest : public GridTest {
 protected:
  void SetUp() override {
    extra_args_ = {"--grid-flush-ms", "3600000", "--grid-extract-every", "5"};
    ServerFixture::SetUp();
  }
};

TEST_F(GridEveryTest, TheExtractorRunsEveryNScans) {
  auto grid_decisions = [&] {
    std::size_t n = 0;
    const json log = get_json("/api/v1/decisions");  // kept: a range-for over a temporary's member would dangle
    for (const auto& d : log["decisions"]) n += d["origin"] == "grid";
    return n;
  };
  const std::vector<std::pair<double, double>> poses = {{3, 3}, {5, 2}, {2, 4.5}, {6.5, 4}, {4, 1.5}};
  for (std::size_t i = 0; i + 1 < poses.size(); ++i) post_scan(room_scan(poses[i].first, poses[i].second, 0.3));
  EXPECT_EQ(grid_decisions(), 0u);
  const auto fifth = post_scan(room_scan(poses.back().first, poses.back().second, 0.3));  // the fifth grid update
  EXPECT_EQ(fifth["grid_revision"], 5);
  EXPECT_GE(grid_decisions(), 4u);
}

// A network file that drops sonar processing: sonar scans are refused with the reason and change nothing; laser
// scans, their lines and the periodic grid line extractor (every 50 scans in that file) go on.
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
  for (int i = 0; i < 3 && !saw_scan; ++i) {
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
