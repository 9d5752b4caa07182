#include "fusion/geometry/angle.h"

#include <cmath>
#include <numbers>

namespace wm::fusion {

double normalize_angle(double angle_rad) {
  constexpr double kPi = std::numbers::pi;
  if (!std::isfinite(angle_rad)) return angle_rad;
  // std::remainder is exact and lands in [−π, π]; only the lower end needs moving to close the interval at +π.
  double wrapped = std::remainder(angle_rad, 2.0 * kPi);
  if (wrapped <= -kPi) wrapped += 2.0 * kPi;
  return wrapped;
}

}  // namespace wm::fusion
