#pragma once

namespace wm::fusion {

/// Wraps an angle into (−π, π] [rad]. −π maps to +π so that every direction has exactly one value.
/// Non-finite input is returned unchanged (NaN stays NaN).
double normalize_angle(double angle_rad);

}  // namespace wm::fusion
