// Real laser logs replayed through the running wmd with wmctl, and the exported map checked the way ROS
// map_server reads it: walls where the robot saw walls, at least as well as a naive 5 cm Bayes grid.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <unordered_map>

#include "e2e_fixture.h"
#include "logs/carmen_log_reader.h"

namespace wm::testing {
namespace {

// A map as map_server loads it: occupied / free / unknown per pixel from the PGM and the YAML's thresholds.
struct LoadedMap {
  double resolution = 0, origin_x = 0, origin_y = 0, occupied_thresh = 0, free_thresh = 0;
  int width = 0, height = 0;
  std::vector<unsigned char> pixels;

  static LoadedMap load(const std::filesystem::path& yaml_path) {
    LoadedMap m;
    std::ifstream yaml(yaml_path);
    std::string image;
    for (std::string line; std::getline(yaml, line);) {
      const auto colon = line.find(':');
      if (colon == std::string::npos) continue;
      const auto key = line.substr(0, colon);
      const auto value = line.substr(colon + 2);
      if (key == "image")
        image = value;
      else if (key == "resolution")
        m.resolution = std::stod(value);
      else if (key == "origin")
        std::sscanf(value.c_str(), "[%lf, %lf", &m.origin_x, &m.origin_y);
      else if (key == "occupied_thresh")
        m.occupied_thresh = std::stod(value);
      else if (key == "free_thresh")
        m.free_thresh = std::stod(value);
      else if (key == "negate") {
        EXPECT_EQ(value, "0");
      }
    }
    std::ifstream pgm(yaml_path.parent_path() / image, std::ios::binary);
    std::string magic;
    int maxval = 0;
    pgm >> magic;
    pgm >> std::ws;
    while (pgm.peek() == '#') {
      std::string comment;
      std::getline(pgm, comment);
    }
    pgm >> m.width >> m.height >> maxval;
    pgm.get();
    EXPECT_EQ(magic, "P5");
    EXPECT_EQ(maxval, 255);
    m.pixels.resize(static_cast<std::size_t>(m.width * m.height));
    pgm.read(reinterpret_cast<char*>(m.pixels.data()), static_cast<std::streamsize>(m.pixels.size()));
    EXPECT_EQ(pgm.gcount(), static_cast<std::streamsize>(m.pixels.size()));
    return m;
  }
  // map_server: p = (255 − value) / 255 with negate 0; occupied above occupied_thresh.
  bool occupied(long cx, long cy) const {
    if (cx < 0 || cy < 0 || cx >= width || cy >= height) return false;
    const auto value = pixels[static_cast<std::size_t>((height - 1 - cy) * width + cx)];
    return (255.0 - value) / 255.0 > occupied_thresh;
  }
  bool occupied_near(double x, double y) const {
    const long cx = static_cast<long>(std::floor((x - origin_x) / resolution));
    const long cy = static_cast<long>(std::floor((y - origin_y) / resolution));
    for (long dy = -1; dy <= 1; ++dy)
      for (long dx = -1; dx <= 1; ++dx)
        if (occupied(cx + dx, cy + dy)) return true;
    return false;
  }
};

// The beams of a log (world frame). A beam with a return within `max_range` ends in a hit; longer ones and
// "no return" readings only clear space up to `max_range` (as the server's grid does: OctoMap's maxrange).
struct Beam {
  double sx, sy, ex, ey;
  bool hit;
};
std::vector<Beam> beams_of(const std::filesystem::path& log, double max_range, std::size_t every) {
  std::vector<Beam> beams;
  logs::CarmenLogReader reader(log);
  std::size_t n = 0;
  while (auto s = reader.next()) {
    if (n++ % every != 0) continue;
    const auto& scan = s->scan;
    for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
      const double r = scan.ranges_m[i];
      if (!std::isfinite(r) || r < scan.range_min_m) continue;
      const bool hit = r < scan.range_max_m && r <= max_range;
      const double reach = hit ? r : max_range;
      const double a = scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
      const auto end = scan.sensor_pose.transform_point({reach * std::cos(a), reach * std::sin(a)});
      beams.push_back({scan.sensor_pose.x_m, scan.sensor_pose.y_m, end.x(), end.y(), hit});
    }
  }
  return beams;
}

// The baseline of the issue: log-odds per 5 cm cell, thin Bresenham rays, hit 0.7 / miss 0.4, clamped.
double naive_grid_score(const std::vector<Beam>& beams) {
  constexpr double kRes = 0.05, kHit = 0.8473, kMiss = -0.4055;
  std::unordered_map<long long, double> cells;
  auto key = [](long x, long y) { return (static_cast<long long>(x) << 32) ^ (y & 0xffffffffLL); };
  auto cell = [&](double v) { return static_cast<long>(std::floor(v / kRes)); };
  for (const auto& b : beams) {
    long x0 = cell(b.sx), y0 = cell(b.sy);
    const long x1 = cell(b.ex), y1 = cell(b.ey);
    const long dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0), sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
    long err = dx + dy;
    while (x0 != x1 || y0 != y1) {
      auto& l = cells[key(x0, y0)];
      l = std::max(-2.0, l + kMiss);
      const long e2 = 2 * err;
      if (e2 >= dy) {
        err += dy;
        x0 += sx;
      }
      if (e2 <= dx) {
        err += dx;
        y0 += sy;
      }
    }
    auto& l = cells[key(x1, y1)];
    l = b.hit ? std::min(3.5, l + kHit) : std::max(-2.0, l + kMiss);
  }
  std::size_t near = 0, hits = 0;
  for (const auto& b : beams) {
    if (!b.hit) continue;
    ++hits;
    bool found = false;
    for (long dy = -1; dy <= 1 && !found; ++dy)
      for (long dx = -1; dx <= 1 && !found; ++dx) {
        const auto it = cells.find(key(cell(b.ex) + dx, cell(b.ey) + dy));
        found = it != cells.end() && 1.0 - 1.0 / (1.0 + std::exp(it->second)) > 0.65;
      }
    near += found;
  }
  return static_cast<double>(near) / static_cast<double>(hits);
}

class ReplayTest : public ServerFixture {
 protected:
  void SetUp() override {
    extra_args_ = {"--sync", "normal"};
    ServerFixture::SetUp();
  }

  // Replays the log with wmctl, exports the map_server pair, and scores it against the log's returns.
  void replay_and_check(const std::string& log_name, std::size_t every) {
    // Only the Intel log is shipped in tests/data (the Freiburg one is 2 MB): without it the test fails, naming it.
    const auto log = real_data("carmen/" + log_name, log_name == "intel-corrected.log.gz" ? "carmen/" + log_name : "");
    const auto wmctl = std::string(WM_WMCTL_PATH) + " --server " + server_->url();
    auto r = run_command(wmctl + " --json replay " + log.string() + " --every " + std::to_string(every));
    ASSERT_EQ(r.status, 0) << r.output;
    const auto summary = json::parse(r.output.substr(r.output.find('{')));
    EXPECT_GT(summary["scans_posted"].get<int>(), 100);
    const auto out = dir_.path() / (log_name + ".pgm");
    r = run_command(wmctl + " grid --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto map = LoadedMap::load(std::filesystem::path(out).replace_extension(".yaml"));
    EXPECT_DOUBLE_EQ(map.resolution, 0.05);

    const auto beams = beams_of(log, 20.0, every);  // the grid's usable range (beyond it a reading only clears)
    std::size_t near = 0, hits = 0;
    for (const auto& b : beams) {
      if (!b.hit) continue;
      ++hits;
      near += map.occupied_near(b.ex, b.ey);
    }
    const double ours = static_cast<double>(near) / static_cast<double>(hits);
    const double naive = naive_grid_score(beams);
    std::cout << log_name << ": " << hits << " returns within one cell of an occupied cell: wmd " << ours
              << ", naive 5 cm Bayes grid " << naive << ", " << summary["scans_per_second"] << " scans/s\n";
    EXPECT_GE(ours, naive) << log_name;

    // Segments longer than 1 m that lie on the grid's walls (80 % of 21 samples within one cell of an occupied
    // cell), of all segments longer than 1 m.
    auto on_walls = [&](const std::vector<json>& segments) {
      std::size_t long_segments = 0, on = 0;
      for (const auto& e : segments) {
        if (e["length"].get<double>() < 1.0) continue;
        ++long_segments;
        const double x0 = e["p0"][0], y0 = e["p0"][1], x1 = e["p1"][0], y1 = e["p1"][1];
        int samples = 0, hits = 0;
        for (double t = 0; t <= 1.0; t += 0.05, ++samples)
          hits += map.occupied_near(x0 + t * (x1 - x0), y0 + t * (y1 - y0));
        on += hits >= 0.8 * samples;
      }
      return std::pair{on, long_segments};
    };

    // The vector map's long walls lie on the grid's walls (the scan line extractor fed it).
    const json elements = get_json("/api/v1/elements")["elements"];
    const auto [on_scan, long_scan] = on_walls(std::vector<json>(elements.begin(), elements.end()));
    ASSERT_GT(long_scan, 20u);
    std::cout << log_name << ": " << on_scan << " of " << long_scan
              << " map elements longer than 1 m lie on occupied cells\n";
    // Measured here, every third scan: Intel 133 of 136 (0.98), Freiburg-079 90 of 96 (0.94). Before elements were
    // gated in their own frame and joined: 293 of 317 (0.92) and 305 of 340 (0.90); joined but before elements
    // were trimmed to what the grid backs: 149 of 161 (0.93) and 131 of 156 (0.84).
    EXPECT_GE(static_cast<double>(on_scan), 0.90 * static_cast<double>(long_scan));

    // The grid line extractor on the same grid: what it observes lies on the walls it was extracted from.
    const json extracted = send_json("POST", "/api/v1/grid/extract", json::object());
    std::vector<json> observed;
    for (const auto& d : extracted["decisions"]) {
      if (d["origin"] == "element") continue;  // two elements joined after a merge (maintenance), not a grid line
      if (d["action"] == "trim") continue;     // an element's end cut where it ran past a wall: not a grid line
      EXPECT_EQ(d["origin"], "grid");
      json segment = d["observed"];
      const double dx = segment["p1"][0].get<double>() - segment["p0"][0].get<double>();
      const double dy = segment["p1"][1].get<double>() - segment["p0"][1].get<double>();
      segment["length"] = std::hypot(dx, dy);
      observed.push_back(segment);
    }
    const auto [on_grid, long_grid] = on_walls(observed);
    ASSERT_GT(long_grid, 20u);
    std::cout << log_name << ": " << on_grid << " of " << long_grid
              << " grid-extracted segments longer than 1 m lie on occupied cells\n";
    EXPECT_GE(static_cast<double>(on_grid), 0.9 * static_cast<double>(long_grid));
  }
};

TEST_F(ReplayTest, IntelLabMapHasWallsWhereTheRobotSawThem) { replay_and_check("intel-corrected.log.gz", 1); }

TEST_F(ReplayTest, Freiburg079MapHasWallsWhereTheRobotSawThem) { replay_and_check("freiburg-079-corrected.log.gz", 3); }

}  // namespace
}  // namespace wm::testing
