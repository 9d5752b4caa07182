#pragma once

// The 8 m × 6 m room the grid tests scan, exact 360° laser scans of it, and the fixture that posts them to a wmd
// whose grid is only flushed by hand (so the journal and its replay are what keeps scans across a crash).
#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "e2e_fixture.h"

namespace wm::testing::grid_room {

struct Wall {
  double ax, ay, bx, by;
};

// The room of these tests: 8 m × 6 m.
inline const std::vector<Wall> kRoom = {{0, 0, 8, 0}, {8, 0, 8, 6}, {8, 6, 0, 6}, {0, 6, 0, 0}};

inline std::optional<double> cast(double px, double py, double angle) {
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
inline json room_scan(double x, double y, double theta) {
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

}  // namespace wm::testing::grid_room
