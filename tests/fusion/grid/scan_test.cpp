#include "fusion/grid/scan.h"

#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>

namespace wm::fusion {
namespace {

LaserScan good_laser() {
  LaserScan s;
  s.sensor_pose = {1.0, 2.0, 0.5};
  s.angle_min_rad = -1.5;
  s.angle_increment_rad = 0.01;
  s.ranges_m = {1.0, std::numeric_limits<double>::quiet_NaN(), -1.0};  // bad readings are per-beam, not errors
  s.range_min_m = 0.1;
  s.range_max_m = 30.0;
  return s;
}

SonarScan good_sonar() {
  SonarScan s;
  s.angles_rad = {0.0, 0.5};
  s.ranges_m = {1.0, 2.0};
  s.range_max_m = 5.0;
  return s;
}

TEST(ScanTest, AcceptsConsistentScans) {
  EXPECT_NO_THROW(validate(good_laser()));
  EXPECT_NO_THROW(validate(good_sonar()));
  LaserScan empty = good_laser();
  empty.ranges_m.clear();
  EXPECT_NO_THROW(validate(empty));
}

TEST(ScanTest, RejectsInconsistentLaserScans) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto bad = [](auto mutate) {
    LaserScan s = good_laser();
    mutate(s);
    return s;
  };
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.sensor_pose.x_m = nan; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.sensor_pose.theta_rad = nan; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.angle_increment_rad = nan; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.angle_min_rad = std::numeric_limits<double>::infinity(); })),
               std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.range_max_m = s.range_min_m; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.range_max_m = std::numeric_limits<double>::infinity(); })),
               std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.range_min_m = -0.1; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.sigma_range_m = -0.01; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.sigma_range_per_m = -0.001; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.sigma_range_per_m = nan; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.sigma_range_per_m = 1.5; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.sigma_range_m = kMaxSigmaRangeM * 1.01; })), std::invalid_argument);
  EXPECT_NO_THROW(validate(bad([&](LaserScan& s) { s.sigma_range_m = kMaxSigmaRangeM; })));
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.usable_range_m = -1; })), std::invalid_argument);
  EXPECT_THROW(validate(bad([&](LaserScan& s) { s.usable_range_m = std::numeric_limits<double>::infinity(); })),
               std::invalid_argument);
  EXPECT_NO_THROW(validate(bad([&](LaserScan& s) { s.usable_range_m = 0; })));  // 0: the grid's own
}

TEST(ScanTest, RejectsInconsistentSonarScans) {
  SonarScan sizes = good_sonar();
  sizes.ranges_m.push_back(1.0);
  EXPECT_THROW(validate(sizes), std::invalid_argument);
  SonarScan angle = good_sonar();
  angle.angles_rad[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(validate(angle), std::invalid_argument);
  SonarScan wide = good_sonar();
  wide.beam_width_rad = kMaxBeamWidthRad;
  EXPECT_THROW(validate(wide), std::invalid_argument);
  SonarScan negative = good_sonar();
  negative.beam_width_rad = -0.1;
  EXPECT_THROW(validate(negative), std::invalid_argument);
  SonarScan range = good_sonar();
  range.range_max_m = 0.0;
  EXPECT_THROW(validate(range), std::invalid_argument);
  // A kilometre-wide σ would make every echo a band kilometres thick (the sonar gate once walked one out of memory).
  SonarScan blurred = good_sonar();
  blurred.sigma_range_m = 1285.0;
  EXPECT_THROW(validate(blurred), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
