#include "clients/robot/servosila_units.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace wm::robot {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(VelocityConverterTest, ConstantsAreTheMeasuredOnes) {
  EXPECT_DOUBLE_EQ(kDriveUnitsPerMps, 72021.73913);
  EXPECT_DOUBLE_EQ(kTurnUnitsPerRadps, 24000.0);
  EXPECT_DOUBLE_EQ(kMinimumLinearMps, 0.2);
  EXPECT_DOUBLE_EQ(kMinimumAngularRadps, 0.2);
}

// The linear runs (units, m/s measured by timing 40 turns of the 1.15 m track) and the angular ones
// (units, rad/s): the constants reproduce each within 1 %.
TEST(VelocityConverterTest, ConstantsReproduceTheCalibrationRuns) {
  const VelocityConverter converter;
  const double linear[][2] = {{6000, 0.08333333333}, {9000, 0.125},         {12000, 0.1666666667},
                              {15000, 0.2081447964}, {18000, 0.25},         {21000, 0.2911392405},
                              {24000, 0.3333333333}, {27000, 0.3770491803}, {30000, 0.4144144144}};
  for (const auto& [units, mps] : linear) {
    const Velocity v = converter.to_velocity(AxisCommand{static_cast<std::int16_t>(-units), 0});
    EXPECT_NEAR(v.linear_mps, mps, 0.01 * mps) << units;
  }
  const double angular[][2] = {
      {10000, 0.4166666667}, {15000, 0.625}, {20000, 0.8333333333}, {25000, 1.045454545}, {30000, 1.25}};
  for (const auto& [units, radps] : angular) {
    const Velocity v = converter.to_velocity(AxisCommand{0, static_cast<std::int16_t>(-units)});
    EXPECT_NEAR(v.angular_radps, radps, 0.01 * radps) << units;
  }
}

TEST(VelocityConverterTest, ForwardIsNegativeDriveAxisAndLeftTurnIsNegativeTurnAxis) {
  VelocityConverter converter;
  // 0.25 m/s · 72021.73913 = 18005.43 → 18005; 0.5 rad/s · 24000 = 12000.
  const ConversionResult r = converter.convert(0.25, 0.5);
  EXPECT_EQ(r.axes, (AxisCommand{-18005, -12000}));
  EXPECT_FALSE(r.rejected || r.clamped || r.raised || r.saturated);
  EXPECT_NEAR(r.sent.linear_mps, 18005 / 72021.73913, 1e-12);
  EXPECT_DOUBLE_EQ(r.sent.angular_radps, 0.5);
  EXPECT_EQ(converter.convert(-0.25, -0.5).axes, (AxisCommand{18005, 12000}));
}

TEST(VelocityConverterTest, ZeroIsAStop) {
  VelocityConverter converter;
  const ConversionResult r = converter.convert(0.0, -0.0);
  EXPECT_EQ(r.axes, (AxisCommand{0, 0}));
  EXPECT_FALSE(r.rejected || r.raised);
}

TEST(VelocityConverterTest, ClampsToConfiguredLimits) {
  VelocityConverter converter;  // 0.4 m/s, 1.25 rad/s
  ConversionResult r = converter.convert(1.0, 3.0);
  // 0.4 · 72021.73913 = 28808.70 → 28809; 1.25 · 24000 = 30000.
  EXPECT_EQ(r.axes, (AxisCommand{-28809, -30000}));
  EXPECT_TRUE(r.clamped);
  r = converter.convert(-1.0, -3.0);
  EXPECT_EQ(r.axes, (AxisCommand{28809, 30000}));
  EXPECT_EQ(converter.clamped_count(), 2u);

  VelocityConverterOptions slow;
  slow.max_linear_mps = 0.3;
  slow.max_angular_radps = 0.5;
  VelocityConverter limited(slow);
  // 0.3 · 72021.73913 = 21606.52 → 21607.
  EXPECT_EQ(limited.convert(0.35, 0.6).axes, (AxisCommand{-21607, -12000}));
}

TEST(VelocityConverterTest, RaisesSmallNonZeroCommandsToTheMinimumWithTheirSign) {
  VelocityConverter converter;
  // 0.2 m/s · 72021.73913 = 14404.35 → 14404; 0.2 rad/s · 24000 = 4800.
  ConversionResult r = converter.convert(0.05, 0.01);
  EXPECT_EQ(r.axes, (AxisCommand{-14404, -4800}));
  EXPECT_TRUE(r.raised);
  EXPECT_EQ(converter.convert(-0.05, -0.01).axes, (AxisCommand{14404, 4800}));
  EXPECT_EQ(converter.convert(1e-9, 0.0).axes, (AxisCommand{-14404, 0}));  // any non-zero value, as the seed says
  // At the minimum itself nothing is raised.
  r = converter.convert(0.2, 0.2);
  EXPECT_FALSE(r.raised);
  EXPECT_EQ(r.axes, (AxisCommand{-14404, -4800}));
  EXPECT_EQ(converter.raised_count(), 3u);
  EXPECT_EQ(converter.min_drive_units(), 14404);
  EXPECT_EQ(converter.min_turn_units(), 4800);
}

TEST(VelocityConverterTest, ZeroMinimumDisablesRaising) {
  VelocityConverterOptions options;
  options.min_linear_mps = 0.0;
  options.min_angular_radps = 0.0;
  VelocityConverter converter(options);
  // 0.05 · 72021.73913 = 3601.09 → 3601; 0.01 · 24000 = 240.
  EXPECT_EQ(converter.convert(0.05, 0.01).axes, (AxisCommand{-3601, -240}));
}

TEST(VelocityConverterTest, NonFiniteCommandIsAStopAndCountedAsRejected) {
  VelocityConverter converter;
  for (const auto& [v, w] :
       {std::pair{std::nan(""), 0.0}, std::pair{0.1, std::nan("")}, std::pair{kInf, 0.0}, std::pair{0.3, -kInf}}) {
    const ConversionResult r = converter.convert(v, w);
    EXPECT_TRUE(r.rejected);
    EXPECT_EQ(r.axes, (AxisCommand{0, 0}));
    EXPECT_EQ(r.sent.linear_mps, 0.0);
    EXPECT_EQ(r.sent.angular_radps, 0.0);
  }
  EXPECT_EQ(converter.rejected_count(), 4u);
  EXPECT_FALSE(converter.convert(0.1, 0.0).rejected);
  EXPECT_EQ(converter.rejected_count(), 4u);
}

TEST(VelocityConverterTest, SaturatesToInt16WhenLimitsExceedTheAxisRange) {
  VelocityConverterOptions fast;
  fast.max_linear_mps = 1.0;     // 72022 units: beyond int16
  fast.max_angular_radps = 2.0;  // 48000 units
  VelocityConverter converter(fast);
  ConversionResult r = converter.convert(1.0, 2.0);
  EXPECT_TRUE(r.saturated);
  EXPECT_EQ(r.axes, (AxisCommand{-32768, -32768}));
  r = converter.convert(-1.0, -2.0);
  EXPECT_EQ(r.axes, (AxisCommand{32767, 32767}));
  EXPECT_FALSE(converter.convert(0.45, 1.3).saturated);  // 32410, 31200
}

TEST(VelocityConverterTest, InverseRecoversTheCommandWithinOneUnit) {
  VelocityConverter converter;
  // Integer steps, so that zero is exactly zero (a tiny non-zero value would be raised to the minimum).
  const auto expected = [](double x) { return x != 0.0 && std::abs(x) < 0.2 ? std::copysign(0.2, x) : x; };
  for (int i = -32; i <= 32; ++i) {
    for (int j = -10; j <= 10; ++j) {
      const double v = 0.0125 * i;
      const double w = 0.125 * j;
      const Velocity back = converter.to_velocity(converter.convert(v, w).axes);
      EXPECT_NEAR(back.linear_mps, expected(v), 0.5 / kDriveUnitsPerMps) << v;
      EXPECT_NEAR(back.angular_radps, expected(w), 0.5 / kTurnUnitsPerRadps) << w;
    }
  }
}

TEST(VelocityConverterTest, WritesAndReadsTheConfiguredAxes) {
  const VelocityConverter converter;
  ControlPacket packet;
  packet.axes[5] = 77;
  converter.write_axes(AxisCommand{-100, 200}, packet);
  EXPECT_EQ(packet.axes[1], -100);
  EXPECT_EQ(packet.axes[0], 200);
  EXPECT_EQ(packet.axes[5], 77);
  EXPECT_EQ(converter.read_axes(packet), (AxisCommand{-100, 200}));

  VelocityConverterOptions other;
  other.drive_axis = 3;
  other.turn_axis = 2;
  other.drive_sign = 1;
  other.turn_sign = 1;
  VelocityConverter swapped(other);
  ControlPacket p2;
  swapped.write_axes(swapped.convert(0.25, 0.5).axes, p2);
  EXPECT_EQ(p2.axes[3], 18005);
  EXPECT_EQ(p2.axes[2], 12000);
  EXPECT_EQ(p2.axes[0], 0);
  EXPECT_EQ(p2.axes[1], 0);
}

TEST(VelocityConverterTest, RejectsInvalidOptions) {
  const auto invalid = [](auto mutate) {
    VelocityConverterOptions o;
    mutate(o);
    EXPECT_THROW(VelocityConverter{o}, std::invalid_argument);
  };
  invalid([](VelocityConverterOptions& o) { o.drive_units_per_mps = 0.0; });
  invalid([](VelocityConverterOptions& o) { o.turn_units_per_radps = -1.0; });
  invalid([](VelocityConverterOptions& o) { o.drive_units_per_mps = kInf; });
  invalid([](VelocityConverterOptions& o) { o.max_linear_mps = -0.1; });
  invalid([](VelocityConverterOptions& o) { o.max_angular_radps = std::nan(""); });
  invalid([](VelocityConverterOptions& o) { o.min_linear_mps = 0.5; });  // above the 0.4 limit
  invalid([](VelocityConverterOptions& o) { o.min_angular_radps = -0.2; });
  invalid([](VelocityConverterOptions& o) { o.min_linear_mps = std::nan(""); });
  invalid([](VelocityConverterOptions& o) { o.drive_axis = 16; });
  invalid([](VelocityConverterOptions& o) { o.turn_axis = o.drive_axis; });
  invalid([](VelocityConverterOptions& o) { o.drive_sign = 0; });
  invalid([](VelocityConverterOptions& o) { o.turn_sign = 2; });
}

}  // namespace
}  // namespace wm::robot
