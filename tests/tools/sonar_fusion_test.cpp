// Sonar judged by the laser, on real plans as built: a simulated ring of 16 Polaroid-class transducers (30° cones,
// specular reflection at grazing incidence, cross talk) beside a 360° laser, driven through AHG2, GDC1 and the
// Open-RMF office. The fused grid with the gate keeps the laser's walls and adds no false occupied cells; without
// the gate the sonar's specular readings erode the walls and its phantoms leave occupied arcs in free space.
#include <gtest/gtest.h>

#include <cstdio>

#include "tests/support/test_data.h"
#include "tools/truth/sonar.h"

namespace wm::truth {
namespace {

std::filesystem::path data_dir() {
  return testing::real_data("amrl-vectormaps/GDC1.vectormap.json").parent_path().parent_path();
}

TEST(SonarRingTest, ReadingsAreWhatTheModelSays) {
  const auto building = load_building("rmf-office", data_dir(), 1, 40);
  const auto world = build_world(building, Edits{}, 1);
  const LaserOptions laser_options;
  const auto laser = drive(building, world, laser_options, 1);
  SonarOptions options;
  const auto rings = sonar_drive(world, laser, laser_options, options, 1);
  ASSERT_EQ(rings.size(), laser.scans.size());
  std::size_t echoes = 0, specular = 0, cross_talk = 0;
  for (std::size_t s = 0; s < rings.size(); ++s) {
    const auto& ring = rings[s];
    ASSERT_EQ(ring.scan.ranges_m.size(), 16u);
    EXPECT_EQ(ring.scan.sensor_pose.x_m, laser.scans[s].sensor_pose.x_m);
    for (std::size_t k = 0; k < 16; ++k) {
      const double r = ring.scan.ranges_m[k];
      EXPECT_GE(r, options.range_min_m);
      EXPECT_LE(r, options.range_max_m);
      switch (ring.kind[k]) {
        case SonarTruth::echo:
          ++echoes;
          break;
        case SonarTruth::specular_lost:
          ++specular;
          EXPECT_EQ(r, options.range_max_m);
          break;
        case SonarTruth::specular_long:
          ++specular;
          break;
        case SonarTruth::cross_talk:
          ++cross_talk;
          break;
      }
    }
  }
  // Most readings are echoes; grazing walls make specular ones common (a corridor's walls along the robot), and
  // cross talk comes at its rate.
  const double n = 16.0 * rings.size();
  EXPECT_GT(echoes / n, 0.5);
  EXPECT_GT(specular / n, 0.03);
  EXPECT_NEAR(cross_talk / n, options.cross_talk, 0.03);
}

class SonarFusionTest : public ::testing::TestWithParam<const char*> {};

TEST_P(SonarFusionTest, TheGateKeepsTheLaserWallsAndDropsThePhantoms) {
  const auto r = run_sonar_fusion(GetParam(), data_dir(), 1, 150);
  std::printf("%s", format_sonar_table({r}).c_str());
  ASSERT_GT(r.laser_only.wall_cells, 500u) << "the laser mapped walls";
  ASSERT_GT(r.specular, 20u);
  ASSERT_GT(r.cross_talk, 20u);
  // Gated: the walls the laser mapped stay (at most 1 % lost) and no false occupied cells beyond laser-only's + 1 %.
  EXPECT_GE(r.gated.kept_share(), 0.99);
  EXPECT_LE(static_cast<double>(r.gated.false_cells), 1.01 * static_cast<double>(r.laser_only.false_cells) + 5);
  // Most cross talk loses its false hit (dropped, or clipped at a nearer surface the laser sees; the rest lands on
  // an arc where the laser sees a surface too), and no true echo is taken for a phantom.
  EXPECT_GE(static_cast<double>(r.cross_talk_dropped + r.cross_talk_clipped), 0.6 * static_cast<double>(r.cross_talk));
  EXPECT_LE(static_cast<double>(r.echoes_dropped), 0.05 * static_cast<double>(r.readings));
  // Ungated, the same readings do measurable harm: walls lost or false cells added.
  EXPECT_TRUE(r.ungated.kept_share() < r.gated.kept_share() - 0.02 ||
              r.ungated.false_cells > r.gated.false_cells + r.gated.false_cells / 5 + 50)
      << "ungated: kept " << r.ungated.kept_share() << ", false cells " << r.ungated.false_cells;
}

INSTANTIATE_TEST_SUITE_P(Buildings, SonarFusionTest, ::testing::Values("ahg2", "gdc1", "rmf-office"),
                         [](const auto& info) {
                           return std::string(info.param == std::string("rmf-office") ? "rmf_office" : info.param);
                         });

}  // namespace
}  // namespace wm::truth
