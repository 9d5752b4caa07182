#pragma once

#include <string_view>
#include <vector>

// A scripted drive for wm-servosila: "F 2; L 90; F 2; L 90" — F metres forward, B metres back, L degrees to the
// left (counter-clockwise), R degrees to the right, W seconds standing still. Steps are separated by ';' or new
// lines; letters are case-insensitive; '#' starts a comment to the end of the line.

namespace wm::robot {

struct DriveStep {
  enum class Kind { forward, back, left, right, wait };
  Kind kind = Kind::wait;
  double amount = 0.0;  // metres (F, B), degrees (L, R) or seconds (W); finite and ≥ 0
};

/// @throw std::invalid_argument naming the step (1-based) for an unknown letter, a missing, negative, non-finite or
///        absurd (> 1000) amount, or an empty script.
std::vector<DriveStep> parse_drive_script(std::string_view text);

/// One constant command held for a time.
struct DriveSegment {
  double linear_mps = 0.0;
  double angular_radps = 0.0;
  double duration_s = 0.0;
};

/// The timed commands of a script at these speeds: |speed| and |turn speed| are what the robot really gets (pass
/// the converter's sent velocity, after its limits and minimum), > 0. A zero step gives no segment; with
/// pause_s > 0, a stop of that length goes between two moving segments (time for a real robot to settle).
/// @throw std::invalid_argument for a non-positive or non-finite speed, or a negative pause.
std::vector<DriveSegment> plan_drive(const std::vector<DriveStep>& steps, double speed_mps, double turn_speed_radps,
                                     double pause_s = 0.0);

}  // namespace wm::robot
