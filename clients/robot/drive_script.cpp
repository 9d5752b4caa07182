#include "clients/robot/drive_script.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace wm::robot {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

DriveStep parse_step(std::string_view text, std::size_t index) {
  const std::string where = "drive step " + std::to_string(index) + " '" + std::string(text) + "': ";
  DriveStep step;
  switch (std::toupper(static_cast<unsigned char>(text.front()))) {
    case 'F':
      step.kind = DriveStep::Kind::forward;
      break;
    case 'B':
      step.kind = DriveStep::Kind::back;
      break;
    case 'L':
      step.kind = DriveStep::Kind::left;
      break;
    case 'R':
      step.kind = DriveStep::Kind::right;
      break;
    case 'W':
      step.kind = DriveStep::Kind::wait;
      break;
    default:
      throw std::invalid_argument(where + "expected F (metres forward), B (back), L/R (degrees) or W (seconds)");
  }
  const std::string_view number = trim(text.substr(1));
  if (number.empty()) throw std::invalid_argument(where + "missing amount");
  double value = 0.0;
  const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
  if (ec != std::errc() || end != number.data() + number.size()) {
    throw std::invalid_argument(where + "not a number: " + std::string(number));
  }
  if (!std::isfinite(value) || value < 0.0 || value > 1000.0) {
    throw std::invalid_argument(where + "amount must be in [0, 1000] (use B or R for the other way)");
  }
  step.amount = value;
  return step;
}

}  // namespace

std::vector<DriveStep> parse_drive_script(std::string_view text) {
  // Comments first, line by line; then the steps, split at ';' and line ends.
  std::string cleaned;
  while (!text.empty()) {
    const std::size_t eol = text.find('\n');
    const std::string_view line = text.substr(0, eol);
    cleaned.append(line.substr(0, line.find('#')));
    cleaned.push_back('\n');
    text = eol == std::string_view::npos ? std::string_view{} : text.substr(eol + 1);
  }
  std::vector<DriveStep> steps;
  std::string_view rest = cleaned;
  while (!rest.empty()) {
    const std::size_t end = rest.find_first_of(";\n");
    const std::string_view piece = trim(rest.substr(0, end));
    rest = end == std::string_view::npos ? std::string_view{} : rest.substr(end + 1);
    if (!piece.empty()) steps.push_back(parse_step(piece, steps.size() + 1));
  }
  if (steps.empty()) throw std::invalid_argument("drive script: no steps (e.g. \"F 2; L 90; F 2\")");
  return steps;
}

std::vector<DriveSegment> plan_drive(const std::vector<DriveStep>& steps, double speed_mps, double turn_speed_radps,
                                     double pause_s) {
  if (!std::isfinite(speed_mps) || speed_mps <= 0.0) throw std::invalid_argument("plan_drive: speed must be > 0");
  if (!std::isfinite(turn_speed_radps) || turn_speed_radps <= 0.0) {
    throw std::invalid_argument("plan_drive: turn speed must be > 0");
  }
  if (!std::isfinite(pause_s) || pause_s < 0.0) throw std::invalid_argument("plan_drive: pause must be >= 0");
  const double v = std::abs(speed_mps);
  const double w = std::abs(turn_speed_radps);
  std::vector<DriveSegment> segments;
  for (const DriveStep& step : steps) {
    if (step.amount == 0.0) continue;
    DriveSegment s;
    switch (step.kind) {
      case DriveStep::Kind::forward:
        s = {v, 0.0, step.amount / v};
        break;
      case DriveStep::Kind::back:
        s = {-v, 0.0, step.amount / v};
        break;
      case DriveStep::Kind::left:
        s = {0.0, w, step.amount * std::numbers::pi / 180.0 / w};
        break;
      case DriveStep::Kind::right:
        s = {0.0, -w, step.amount * std::numbers::pi / 180.0 / w};
        break;
      case DriveStep::Kind::wait:
        s = {0.0, 0.0, step.amount};
        break;
    }
    const bool moving = s.linear_mps != 0.0 || s.angular_radps != 0.0;
    if (pause_s > 0.0 && moving && !segments.empty() &&
        (segments.back().linear_mps != 0.0 || segments.back().angular_radps != 0.0)) {
      segments.push_back({0.0, 0.0, pause_s});
    }
    segments.push_back(s);
  }
  return segments;
}

}  // namespace wm::robot
