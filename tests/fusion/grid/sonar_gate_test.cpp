#include "fusion/grid/sonar_gate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "fusion/grid/laser_sonar_grids.h"

namespace wm::fusion {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// A 6 m × 4 m room with its lower-left corner at the origin (offset from the cell borders).
struct Room {
  double x0 = 0.013, y0 = -0.021, w = 6.0, h = 4.0;
  double cast(double px, double py, double a) const {
    const double ux = std::cos(a), uy = std::sin(a);
    double t = std::numeric_limits<double>::infinity();
    if (ux > 1e-12) t = std::min(t, (x0 + w - px) / ux);
    if (ux < -1e-12) t = std::min(t, (x0 - px) / ux);
    if (uy > 1e-12) t = std::min(t, (y0 + h - py) / uy);
    if (uy < -1e-12) t = std::min(t, (y0 - py) / uy);
    return t;
  }
};

LaserScan laser_at(const Room& room, const Pose2D& pose) {
  LaserScan scan;
  scan.sensor_pose = pose;
  scan.angle_min_rad = -std::numbers::pi;
  scan.angle_increment_rad = 0.5 * kDeg;
  scan.range_min_m = 0.05;
  scan.range_max_m = 20;
  for (int i = 0; i < 720; ++i)
    scan.ranges_m.push_back(room.cast(pose.x_m, pose.y_m, pose.theta_rad + scan.angle_min_rad + i * 0.5 * kDeg));
  return scan;
}

// The laser has seen the whole room from five places.
LaserSonarGrids mapped_room(const Room& room, const LaserSonarOptions& options = {}) {
  LaserSonarGrids grids(GridOptions{}, options);
  for (const Pose2D& pose : {Pose2D{1.5, 1.0, 0.3}, Pose2D{3.0, 2.0, -1.0}, Pose2D{4.7, 3.1, 2.0},
                             Pose2D{2.2, 3.0, 0.0}, Pose2D{5.1, 0.8, 1.2}})
    grids.insert(laser_at(room, pose));
  return grids;
}

// One transducer looking along +x from (2, 2): the east wall is 4.01 m away.
SonarScan sonar_east(double reading) {
  SonarScan scan;
  scan.sensor_pose = {2.0, 2.0, 0.0};
  scan.angles_rad = {0.0};
  scan.ranges_m = {reading};
  scan.beam_width_rad = 30 * kDeg;
  scan.range_min_m = 0.1;
  scan.range_max_m = 10.0;
  return scan;
}

TEST(SonarGateTest, KeepsAReturnTheLaserBacks) {
  const Room room;
  const auto grids = mapped_room(room);
  const auto gated = gate_sonar(sonar_east(room.cast(2.0, 2.0, 0.0) + 0.02), grids.laser_only(), {});
  ASSERT_EQ(gated.verdicts.size(), 1u);
  EXPECT_EQ(gated.verdicts[0], SonarVerdict::kept);
  ASSERT_TRUE(gated.beams[0]);
  EXPECT_TRUE(gated.beams[0]->has_return);
}

TEST(SonarGateTest, DropsAShortReturnWhereTheLaserSawFreeSpace) {
  const Room room;
  const auto grids = mapped_room(room);
  const auto gated = gate_sonar(sonar_east(1.5), grids.laser_only(), {});  // cross talk: nothing is 1.5 m east
  EXPECT_EQ(gated.verdicts[0], SonarVerdict::phantom);
  EXPECT_FALSE(gated.beams[0]);
}

TEST(SonarGateTest, ClipsALongReadingAtTheWallTheLaserSees) {
  const Room room;
  const auto grids = mapped_room(room);
  for (const double reading : {7.0, 10.0}) {  // a specular echo from beyond the wall, and no echo at all
    const auto gated = gate_sonar(sonar_east(reading), grids.laser_only(), {});
    EXPECT_EQ(gated.verdicts[0], SonarVerdict::clipped) << reading;
    ASSERT_TRUE(gated.beams[0]);
    EXPECT_FALSE(gated.beams[0]->has_return);
    // The cone's nearest wall cells (the corners of its 30° at 4 m reach the east wall first) stop its free space.
    EXPECT_LT(gated.beams[0]->range_m, room.cast(2.0, 2.0, 0.0));
    EXPECT_GT(gated.beams[0]->range_m, 1.5);
  }
}

TEST(SonarGateTest, LeavesWhatTheLaserHasNotSeenUnjudged) {
  const Room room;
  const LaserSonarGrids empty(GridOptions{}, {});
  const auto gated = gate_sonar(sonar_east(1.5), empty.laser_only(), {});
  EXPECT_EQ(gated.verdicts[0], SonarVerdict::unjudged);
  EXPECT_TRUE(gated.beams[0]);
  auto nan = sonar_east(std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(gate_sonar(nan, empty.laser_only(), {}).verdicts[0], SonarVerdict::ignored);
}

// The whole point: a specular reading erodes the wall in an ungated fused grid and not in a gated one, and the
// phantom leaves an occupied arc only without the gate.
TEST(SonarGateTest, GatedFusionKeepsTheWallAndDropsThePhantom) {
  const Room room;
  LaserSonarOptions ungated_options;
  ungated_options.gate_sonar = false;
  auto gated = mapped_room(room);
  auto ungated = mapped_room(room, ungated_options);
  const CellIndex wall = cell_at({room.x0 + room.w + 0.01, 2.0}, 0.05);
  const CellIndex phantom_arc = cell_at({3.5, 2.0}, 0.05);
  const double wall_before = gated.fused().log_odds(wall);
  ASSERT_GT(wall_before, 0.62);
  for (int k = 0; k < 20; ++k) {
    for (auto* grids : {&gated, &ungated}) {
      grids->insert(sonar_east(9.0));
      grids->insert(sonar_east(1.5));
    }
  }
  EXPECT_GT(gated.fused().log_odds(wall), 0.62) << "the gate keeps the laser's wall";
  EXPECT_LT(ungated.fused().log_odds(wall), 0.0) << "twenty specular readings wipe it out without the gate";
  EXPECT_LE(gated.fused().log_odds(phantom_arc), gated.laser_only().log_odds(phantom_arc));
  EXPECT_GT(ungated.fused().log_odds(phantom_arc), 0.62);
  EXPECT_EQ(gated.gate_counts().phantom, 20u);
  EXPECT_EQ(gated.gate_counts().clipped, 20u);
  EXPECT_EQ(gated.gate_counts().scans, 40u);
  // The laser-only grid is the same either way, and the sonar-only grid holds the readings as they came.
  EXPECT_EQ(gated.laser_only().log_odds(wall), ungated.laser_only().log_odds(wall));
  ASSERT_NE(gated.sonar_only(), nullptr);
  EXPECT_GT(gated.sonar_only()->log_odds(phantom_arc), 0.62);
}

TEST(SonarGateTest, LayersAnswerTheDecisionAndTheDisagreement) {
  const Room room;
  auto grids = mapped_room(room);
  const GridGeometry region({2.0, 1.0}, 0.05, 84, 40);  // from x = 2 to 6.2 m: the free room and the east wall
  const auto before = grids.export_layer(GridLayer::laser_sonar_conflict, region);
  for (const float v : before) EXPECT_TRUE(std::isnan(v)) << "no sonar yet";
  for (int k = 0; k < 5; ++k) grids.insert(sonar_east(1.5));
  const auto decision = grids.export_layer(GridLayer::ds_decision, region);
  const auto disagreement = grids.export_layer(GridLayer::laser_sonar_conflict, region);
  const auto cell = [&](double x, double y) {
    return static_cast<std::size_t>(std::floor((y - 1.0) / 0.05)) * 84 + static_cast<std::size_t>((x - 2.0) / 0.05);
  };
  EXPECT_EQ(decision[cell(3.0, 2.0)], ds_decision_value(DsDecision::free));
  EXPECT_EQ(decision[cell(room.x0 + room.w + 0.01, 2.0)], ds_decision_value(DsDecision::occupied));
  // Where the phantom arc lies the sonar said occupied and the laser free: strong conflict there, none elsewhere.
  EXPECT_GT(disagreement[cell(3.5, 2.0)], 0.2f);
  EXPECT_TRUE(std::isnan(disagreement[cell(3.0, 1.1)]) || disagreement[cell(3.0, 1.1)] < 0.05f);
}

TEST(SonarGateTest, RefusesBadOptionsAndForeignBeams) {
  SonarGateOptions options;
  options.phantom_seen_share = 0;
  EXPECT_THROW(validate(options), std::invalid_argument);
  options = {};
  options.band_margin_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(validate(options), std::invalid_argument);
  DsDecisionOptions decision;
  decision.free_plausibility_max = 1.0;
  EXPECT_THROW(validate(decision), std::invalid_argument);
  OccupancyGrid grid{GridOptions{}};
  const auto scan = sonar_east(3.0);
  auto beam = sonar_beam(scan, 0, grid.options().sensor);
  ASSERT_TRUE(beam);
  beam->range_m = 50;  // farther than the scan reaches
  EXPECT_THROW(grid.insert(scan, {beam}), std::invalid_argument);
  EXPECT_THROW(grid.insert(scan, {}), std::invalid_argument);
  EXPECT_TRUE(grid.tiles().empty()) << "nothing went in";
}

TEST(GridLayerTest, NamesRoundTrip) {
  for (const auto name : kGridLayerNames) {
    const auto layer = grid_layer_named(name);
    ASSERT_TRUE(layer) << name;
    EXPECT_EQ(to_string(*layer), name);
  }
  EXPECT_FALSE(grid_layer_named("laser"));
}

}  // namespace
}  // namespace wm::fusion
