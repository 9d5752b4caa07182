// wm-servosila's scripted drives: parsing and the timed commands they become.
#include "clients/robot/drive_script.h"

#include <gtest/gtest.h>

#include <numbers>
#include <stdexcept>

namespace wm::robot {
namespace {

TEST(DriveScriptTest, ParsesASquare) {
  const auto steps = parse_drive_script("F 2; L 90; F 2; l 90;f 2 ;L 90; F 2; L 90");
  ASSERT_EQ(steps.size(), 8u);
  EXPECT_EQ(steps[0].kind, DriveStep::Kind::forward);
  EXPECT_EQ(steps[0].amount, 2.0);
  EXPECT_EQ(steps[3].kind, DriveStep::Kind::left);
  EXPECT_EQ(steps[3].amount, 90.0);
  EXPECT_EQ(steps[4].kind, DriveStep::Kind::forward);
}

TEST(DriveScriptTest, LinesCommentsAndEveryKind) {
  const auto steps = parse_drive_script("F 1.5   # out\nB 0.5; R 45 # right; F 9\n\n  W 2\n;;");
  ASSERT_EQ(steps.size(), 4u);
  EXPECT_EQ(steps[0].kind, DriveStep::Kind::forward);
  EXPECT_EQ(steps[1].kind, DriveStep::Kind::back);
  EXPECT_EQ(steps[2].kind, DriveStep::Kind::right);
  EXPECT_EQ(steps[2].amount, 45.0);
  EXPECT_EQ(steps[3].kind, DriveStep::Kind::wait);
  EXPECT_EQ(steps[3].amount, 2.0);
}

TEST(DriveScriptTest, RefusesWhatIsNotAStep) {
  for (const char* bad : {"", " ; ", "X 2", "F", "F two", "F -1", "F 2m", "L nan", "F 1e6", "F 2; L"}) {
    EXPECT_THROW(parse_drive_script(bad), std::invalid_argument) << bad;
  }
  try {
    parse_drive_script("F 2; Q 1");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("step 2"), std::string::npos) << e.what();
  }
}

TEST(DriveScriptTest, PlansTimedCommandsAtTheGivenSpeeds) {
  const auto segments = plan_drive(parse_drive_script("F 2; L 90; B 1; R 180; W 1.5; F 0"), 0.4, 0.5);
  ASSERT_EQ(segments.size(), 5u);
  EXPECT_EQ(segments[0].linear_mps, 0.4);
  EXPECT_DOUBLE_EQ(segments[0].duration_s, 5.0);
  EXPECT_EQ(segments[1].angular_radps, 0.5);
  EXPECT_DOUBLE_EQ(segments[1].duration_s, std::numbers::pi / 2 / 0.5);
  EXPECT_EQ(segments[2].linear_mps, -0.4);
  EXPECT_DOUBLE_EQ(segments[2].duration_s, 2.5);
  EXPECT_EQ(segments[3].angular_radps, -0.5);
  EXPECT_DOUBLE_EQ(segments[3].duration_s, std::numbers::pi / 0.5);
  EXPECT_EQ(segments[4].linear_mps, 0.0);
  EXPECT_EQ(segments[4].angular_radps, 0.0);
  EXPECT_EQ(segments[4].duration_s, 1.5);
}

TEST(DriveScriptTest, PausesGoBetweenMoves) {
  const auto segments = plan_drive(parse_drive_script("F 1; L 90; W 1; F 1"), 0.5, 1.0, 0.25);
  ASSERT_EQ(segments.size(), 5u);  // F, pause, L, W, F
  EXPECT_EQ(segments[1].duration_s, 0.25);
  EXPECT_EQ(segments[1].linear_mps, 0.0);
  EXPECT_EQ(segments[3].duration_s, 1.0);
  EXPECT_THROW(plan_drive(parse_drive_script("F 1"), 0.0, 1.0), std::invalid_argument);
  EXPECT_THROW(plan_drive(parse_drive_script("F 1"), 0.5, -1.0), std::invalid_argument);
  EXPECT_THROW(plan_drive(parse_drive_script("F 1"), 0.5, 1.0, -1.0), std::invalid_argument);
}

}  // namespace
}  // namespace wm::robot
