// A sonar ring judged by the laser: any pose, angles, readings and cone width (as doubles from the input) against a
// room the laser has mapped. Expected: std::invalid_argument for a scan validate() refuses; otherwise a verdict per
// reading, beams that go no farther than the reading's own, and a fused grid that takes them (the gate never hands
// the grid a beam it would refuse).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <numbers>
#include <stdexcept>

#include "fusion/grid/laser_sonar_grids.h"
#include "fuzz/fuzz_support.h"

namespace {

const wm::fusion::LaserSonarGrids& room() {
  static const wm::fusion::LaserSonarGrids grids = [] {
    wm::fusion::LaserSonarGrids g(wm::fusion::GridOptions{}, {});
    // A 6 m × 4 m room seen from its middle.
    wm::fusion::LaserScan scan;
    scan.sensor_pose = {3.0, 2.0, 0.0};
    scan.angle_min_rad = -std::numbers::pi;
    scan.angle_increment_rad = std::numbers::pi / 180;
    scan.range_min_m = 0.05;
    scan.range_max_m = 20;
    for (int i = 0; i < 360; ++i) {
      const double a = scan.angle_min_rad + i * scan.angle_increment_rad, c = std::cos(a), s = std::sin(a);
      double t = 1e9;
      if (c > 1e-9) t = std::min(t, 3.0 / c);
      if (c < -1e-9) t = std::min(t, -3.0 / c);
      if (s > 1e-9) t = std::min(t, 2.0 / s);
      if (s < -1e-9) t = std::min(t, -2.0 / s);
      scan.ranges_m.push_back(t);
    }
    for (int k = 0; k < 3; ++k) g.insert(scan);
    return g;
  }();
  return grids;
}

double next(const std::uint8_t*& data, std::size_t& size) {
  double v = 0;
  if (size >= sizeof v) {
    std::memcpy(&v, data, sizeof v);
    data += sizeof v;
    size -= sizeof v;
  }
  return v;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm::fusion;
  SonarScan scan;
  // Positions near the room, so most inputs reach the gate rather than the growth limits.
  scan.sensor_pose = {std::fmod(next(data, size), 20.0), std::fmod(next(data, size), 20.0), next(data, size)};
  scan.beam_width_rad = next(data, size);
  scan.range_min_m = next(data, size);
  scan.range_max_m = next(data, size);
  scan.sigma_range_m = next(data, size);
  while (size >= 16 && scan.ranges_m.size() < 32) {
    scan.angles_rad.push_back(next(data, size));
    scan.ranges_m.push_back(next(data, size));
  }
  SonarGateResult gated;
  try {
    gated = gate_sonar(scan, room().laser_only(), {});
  } catch (const std::invalid_argument&) {
    return 0;  // validate(scan) refused it
  }
  if (gated.beams.size() != scan.ranges_m.size() || gated.verdicts.size() != scan.ranges_m.size())
    wm::fuzz::fail("the gate did not answer every reading");
  for (std::size_t i = 0; i < gated.beams.size(); ++i) {
    const auto own = sonar_beam(scan, i, room().fused().options().sensor);
    if (!gated.beams[i]) continue;
    if (!own) wm::fuzz::fail("the gate made a beam of an ignored reading");
    if (gated.beams[i]->range_m > own->range_m) wm::fuzz::fail("a gated beam reaches farther than its reading");
  }
  OccupancyGrid fused(room().fused());
  try {
    fused.insert(scan, gated.beams);
  } catch (const std::invalid_argument& e) {
    // Only the growth limit may refuse (a sensor far out): the same scan ungated is refused too.
    try {
      OccupancyGrid plain(room().fused());
      plain.insert(scan);
    } catch (const std::invalid_argument&) {
      return 0;
    }
    wm::fuzz::fail(std::string("the fused grid refused the gate's beams: ") + e.what());
  }
  return 0;
}
