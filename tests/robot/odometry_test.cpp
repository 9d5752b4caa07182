#include "clients/robot/odometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

namespace wm::robot {
namespace {

constexpr double kPi = std::numbers::pi;

/// A telemetry packet with the default track ids (left 0, right 1) at these counts, plus an unrelated motor.
TelemetryPacket tracks(std::uint64_t tick, std::uint32_t left, std::uint32_t right) {
  TelemetryPacket p;
  p.tick = tick;
  MotorRecord arm;
  arm.device_id = 5;
  arm.position = 12345;
  MotorRecord l;
  l.device_id = 0;
  l.position = left;
  MotorRecord r;
  r.device_id = 1;
  r.position = right;
  p.motors = {arm, r, l};  // order in the packet does not matter: records are found by id
  return p;
}

TEST(DiffDriveOdometryTest, FirstPacketIsTheReference) {
  DiffDriveOdometry odometry;
  EXPECT_EQ(odometry.update(tracks(1, 5000, 7000)), OdometryUpdate::started);
  EXPECT_EQ(odometry.pose().x_m, 0.0);
  EXPECT_EQ(odometry.pose().covariance, Eigen::Matrix3d::Zero());
}

// Both tracks run 2 m (10 packets of 2000 counts at 10 000 counts/m): the pose is (2, 0, 0) and the covariance is
// the model's closed form for n equal straight steps of Δs along x: σx² = k_t·L, σθ² = k_θm·L,
// σyθ = Δs·q·n²/2 and σy² = Δs²·q·n(4n² − 1)/12 with q = k_θm·Δs (≈ k_θm·L³/3, the continuous limit).
TEST(DiffDriveOdometryTest, StraightTwoMetreRunMatchesTheAnalyticPoseAndCovariance) {
  const OdometryOptions options;
  DiffDriveOdometry odometry(options);
  odometry.update(tracks(1, 0, 0));
  double previous_trace = 0.0;
  for (std::uint32_t i = 1; i <= 10; ++i) {
    ASSERT_EQ(odometry.update(tracks(1 + i, 2000 * i, 2000 * i)), OdometryUpdate::advanced);
    const double trace = odometry.pose().covariance.trace();
    EXPECT_GT(trace, previous_trace);
    previous_trace = trace;
  }
  const OdometryPose& pose = odometry.pose();
  EXPECT_NEAR(pose.x_m, 2.0, 1e-12);
  EXPECT_EQ(pose.y_m, 0.0);
  EXPECT_EQ(pose.theta_rad, 0.0);

  const double n = 10.0;
  const double ds = 0.2;
  const double q = options.rotation_variance_per_m * ds;
  const Eigen::Matrix3d& p = pose.covariance;
  EXPECT_NEAR(p(0, 0), options.translation_variance_per_m * 2.0, 1e-15);
  EXPECT_NEAR(p(2, 2), options.rotation_variance_per_m * 2.0, 1e-15);
  EXPECT_NEAR(p(1, 2), ds * q * n * n / 2.0, 1e-15);
  EXPECT_NEAR(p(1, 1), ds * ds * q * n * (4.0 * n * n - 1.0) / 12.0, 1e-15);
  EXPECT_NEAR(p(1, 1), options.rotation_variance_per_m * 8.0 / 3.0, 0.01 * p(1, 1));
  EXPECT_EQ(p(0, 1), 0.0);
  EXPECT_EQ(p(0, 2), 0.0);
  EXPECT_EQ(p, p.transpose());
  EXPECT_DOUBLE_EQ(odometry.distance_travelled_m(), 2.0);
}

// Tracks in opposite directions, 4 × 393 counts each: θ = (Δr − Δl)/width = 2·0.1572 m / 0.2 m = 1.572 rad,
// no translation, and only the rotation variance grows, by k_θ·|θ|.
TEST(DiffDriveOdometryTest, TurnOnTheSpotMatchesTheAnalyticAngle) {
  const OdometryOptions options;
  DiffDriveOdometry odometry(options);
  const std::uint32_t start = 1000000;
  odometry.update(tracks(1, start, start));
  for (std::uint32_t i = 1; i <= 4; ++i) {
    ASSERT_EQ(odometry.update(tracks(1 + i, start - 393 * i, start + 393 * i)), OdometryUpdate::advanced);
  }
  const double theta = 2.0 * (4 * 393 / 10000.0) / 0.2;
  const OdometryPose& pose = odometry.pose();
  EXPECT_NEAR(pose.theta_rad, theta, 1e-12);
  EXPECT_EQ(pose.x_m, 0.0);
  EXPECT_EQ(pose.y_m, 0.0);
  EXPECT_NEAR(pose.covariance(2, 2), options.rotation_variance_per_rad * theta, 1e-15);
  EXPECT_EQ(pose.covariance(0, 0), 0.0);
  EXPECT_EQ(pose.covariance(1, 1), 0.0);
  EXPECT_NEAR(odometry.rotation_turned_rad(), theta, 1e-12);
}

TEST(DiffDriveOdometryTest, FullTurnWrapsTheHeadingIntoMinusPiToPi) {
  DiffDriveOdometry odometry;
  odometry.update(tracks(1, 0, 0));
  // 3π/4 per packet: each track moves 0.1 m · 3π/4 = 0.2356 m.
  const std::uint32_t step = static_cast<std::uint32_t>(std::lround(0.1 * 0.75 * kPi * 10000));
  const double dtheta = 2.0 * step / 10000.0 / 0.2;
  odometry.update(tracks(2, 0u - step, step));
  odometry.update(tracks(3, 0u - 2 * step, 2 * step));
  EXPECT_NEAR(odometry.pose().theta_rad, 2.0 * dtheta - 2.0 * kPi, 1e-12);
  EXPECT_LT(odometry.pose().theta_rad, 0.0);
}

// A quarter circle of radius 1 m (tracks on 0.9 m and 1.1 m) in 100 packets ends at (1, 1, π/2) up to the counts'
// 0.1 mm resolution (5·10⁻⁴ rad of heading per count of difference) and the midpoint rule's error.
TEST(DiffDriveOdometryTest, ArcMatchesTheCircle) {
  DiffDriveOdometry odometry;
  odometry.update(tracks(0, 0, 0));
  for (int i = 1; i <= 100; ++i) {
    const double angle = 0.5 * kPi * i / 100.0;
    const auto left = static_cast<std::uint32_t>(std::lround(0.9 * angle * 10000));
    const auto right = static_cast<std::uint32_t>(std::lround(1.1 * angle * 10000));
    ASSERT_EQ(odometry.update(tracks(i, left, right)), OdometryUpdate::advanced);
  }
  EXPECT_NEAR(odometry.pose().x_m, 1.0, 1e-3);
  EXPECT_NEAR(odometry.pose().y_m, 1.0, 1e-3);
  EXPECT_NEAR(odometry.pose().theta_rad, 0.5 * kPi, 1e-3);
}

TEST(DiffDriveOdometryTest, CountsWrapAroundAt32Bits) {
  DiffDriveOdometry odometry;
  const std::uint32_t near_end = 4294967295u - 295u;  // 2^32 − 296
  odometry.update(tracks(1, near_end, near_end));
  EXPECT_EQ(odometry.update(tracks(2, near_end + 2000u, near_end + 2000u)), OdometryUpdate::advanced);  // wraps to 1704
  EXPECT_NEAR(odometry.pose().x_m, 0.2, 1e-12);
  EXPECT_EQ(odometry.update(tracks(3, near_end - 1000u, near_end - 1000u)), OdometryUpdate::advanced);  // back over it
  EXPECT_NEAR(odometry.pose().x_m, -0.1, 1e-12);
}

TEST(DiffDriveOdometryTest, CountsWrapAroundAtConfiguredWidth) {
  OdometryOptions options;
  options.position_bits = 16;
  DiffDriveOdometry odometry(options);
  odometry.update(tracks(1, 65000, 65000));
  EXPECT_EQ(odometry.update(tracks(2, 1464, 1464)), OdometryUpdate::advanced);  // 65000 + 2000 − 65536
  EXPECT_NEAR(odometry.pose().x_m, 0.2, 1e-12);
  EXPECT_EQ(odometry.update(tracks(3, 65000, 65000)), OdometryUpdate::advanced);  // 1464 − 2000 + 65536
  EXPECT_NEAR(odometry.pose().x_m, 0.0, 1e-12);
}

TEST(DiffDriveOdometryTest, SignsMirrorACountThatRunsBackwards) {
  OdometryOptions options;
  options.left_sign = -1;
  DiffDriveOdometry odometry(options);
  odometry.update(tracks(1, 10000, 10000));
  odometry.update(tracks(2, 8000, 12000));  // left count falls, but that track drives forward too
  EXPECT_NEAR(odometry.pose().x_m, 0.2, 1e-12);
  EXPECT_EQ(odometry.pose().theta_rad, 0.0);
}

TEST(DiffDriveOdometryTest, IgnoresLateAndDuplicatePacketsAndSurvivesARestart) {
  DiffDriveOdometry odometry;
  odometry.update(tracks(100, 0, 0));
  EXPECT_EQ(odometry.update(tracks(102, 2000, 2000)), OdometryUpdate::advanced);
  EXPECT_EQ(odometry.update(tracks(101, 1000, 1000)), OdometryUpdate::stale);  // reordered
  EXPECT_EQ(odometry.update(tracks(102, 2000, 2000)), OdometryUpdate::stale);  // duplicate
  EXPECT_NEAR(odometry.pose().x_m, 0.2, 1e-12);
  EXPECT_EQ(odometry.update(tracks(103, 3000, 3000)), OdometryUpdate::advanced);
  EXPECT_NEAR(odometry.pose().x_m, 0.3, 1e-12);

  DiffDriveOdometry restarted;
  restarted.update(tracks(5000, 70000, 70000));
  EXPECT_EQ(restarted.update(tracks(3, 0, 0)), OdometryUpdate::started);  // far behind: the robot restarted
  EXPECT_EQ(restarted.update(tracks(4, 1000, 1000)), OdometryUpdate::advanced);
  EXPECT_NEAR(restarted.pose().x_m, 0.1, 1e-12);
}

TEST(DiffDriveOdometryTest, IgnoresPacketWithoutBothTracks) {
  DiffDriveOdometry odometry;
  TelemetryPacket only_left = tracks(1, 0, 0);
  only_left.motors.erase(only_left.motors.begin() + 1);  // drop the right track (id 1)
  EXPECT_EQ(odometry.update(only_left), OdometryUpdate::track_missing);
  odometry.update(tracks(2, 0, 0));
  TelemetryPacket none;
  none.tick = 3;
  EXPECT_EQ(odometry.update(none), OdometryUpdate::track_missing);
  EXPECT_EQ(odometry.update(tracks(4, 1000, 1000)), OdometryUpdate::advanced);
  EXPECT_NEAR(odometry.pose().x_m, 0.1, 1e-12);
}

TEST(DiffDriveOdometryTest, RejectsAJumpAndContinuesFromTheNewCounts) {
  DiffDriveOdometry odometry;  // max step 1 m = 10 000 counts
  odometry.update(tracks(1, 0, 0));
  EXPECT_EQ(odometry.update(tracks(2, 500000, 500000)), OdometryUpdate::jump_rejected);
  EXPECT_EQ(odometry.pose().x_m, 0.0);
  EXPECT_EQ(odometry.update(tracks(3, 502000, 502000)), OdometryUpdate::advanced);
  EXPECT_NEAR(odometry.pose().x_m, 0.2, 1e-12);
}

TEST(DiffDriveOdometryTest, AdvanceIntegratesCommandedMotion) {
  OdometryPose start;
  start.theta_rad = 0.5 * kPi;
  DiffDriveOdometry odometry({}, start);
  for (int i = 0; i < 20; ++i) odometry.advance(0.3 * 0.05, 0.0);  // 0.3 m/s for 1 s in 50 ms steps
  EXPECT_NEAR(odometry.pose().x_m, 0.0, 1e-12);
  EXPECT_NEAR(odometry.pose().y_m, 0.3, 1e-12);
  EXPECT_NEAR(odometry.pose().covariance(1, 1), 0.0025 * 0.3, 1e-12);  // along y now
  EXPECT_THROW(odometry.advance(std::nan(""), 0.0), std::invalid_argument);
  EXPECT_NEAR(odometry.pose().y_m, 0.3, 1e-12);
}

TEST(DiffDriveOdometryTest, SetPoseKeepsTheEncoderReference) {
  DiffDriveOdometry odometry;
  odometry.update(tracks(1, 0, 0));
  OdometryPose fix;
  fix.x_m = 5.0;
  fix.y_m = -1.0;
  odometry.set_pose(fix);
  odometry.update(tracks(2, 1000, 1000));
  EXPECT_NEAR(odometry.pose().x_m, 5.1, 1e-12);
  EXPECT_EQ(odometry.pose().y_m, -1.0);
}

TEST(DiffDriveOdometryTest, RejectsInvalidOptionsAndPoses) {
  const auto invalid = [](auto mutate) {
    OdometryOptions o;
    mutate(o);
    EXPECT_THROW(DiffDriveOdometry{o}, std::invalid_argument);
  };
  invalid([](OdometryOptions& o) { o.right_track_id = o.left_track_id; });
  invalid([](OdometryOptions& o) { o.position_units_per_m = 0.0; });
  invalid([](OdometryOptions& o) { o.track_width_m = -0.2; });
  invalid([](OdometryOptions& o) { o.track_width_m = std::nan(""); });
  invalid([](OdometryOptions& o) { o.max_step_m = 0.0; });
  invalid([](OdometryOptions& o) { o.left_sign = 0; });
  invalid([](OdometryOptions& o) { o.right_sign = -2; });
  invalid([](OdometryOptions& o) { o.position_bits = 0; });
  invalid([](OdometryOptions& o) { o.position_bits = 33; });
  invalid([](OdometryOptions& o) { o.translation_variance_per_m = -1e-3; });
  invalid([](OdometryOptions& o) { o.rotation_variance_per_rad = std::nan(""); });
  invalid([](OdometryOptions& o) { o.rotation_variance_per_m = std::numeric_limits<double>::infinity(); });
  OdometryPose bad;
  bad.x_m = std::nan("");
  EXPECT_THROW(DiffDriveOdometry({}, bad), std::invalid_argument);
  DiffDriveOdometry odometry;
  EXPECT_THROW(odometry.set_pose(bad), std::invalid_argument);
}

}  // namespace
}  // namespace wm::robot
