// Scans through the running wmd: both grids, the map_server export, persistence, scan lines, grid lines.
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

}  // namespace
}  // namespace wm::testing
