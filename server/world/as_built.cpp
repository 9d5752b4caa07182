#include "server/world/as_built.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace wm::world {
namespace {

Displacement displacement(const ObjectState& object) {
  const auto& drawn = object.plan->pose;
  const auto& now = object.body.pose();
  Displacement d;
  d.dx_m = now.x_m - drawn.x_m;
  d.dy_m = now.y_m - drawn.y_m;
  d.dtheta_rad = std::remainder(now.theta_rad - drawn.theta_rad, 2 * std::numbers::pi);
  d.distance_m = std::hypot(d.dx_m, d.dy_m);
  d.sigma_xy_m = std::sqrt(std::max(object.body.pose_cov()(0, 0), object.body.pose_cov()(1, 1)));
  return d;
}

}  // namespace

AsBuiltReport as_built_report(const WorldState& state) {
  AsBuiltReport report;
  report.objects.reserve(state.objects.size());
  for (const auto& object : state.objects) {
    ObjectAsBuilt entry{&object, AsBuiltStatus::never_observed, std::nullopt};
    // An adjustment says more than any number of confirmations: the object is not where it was drawn.
    if (object.adjustments > 0) {
      entry.status = AsBuiltStatus::moved;
      entry.moved_by = displacement(object);
      ++report.moved;
    } else if (object.confirmations > 0) {
      entry.status = AsBuiltStatus::confirmed;
      ++report.confirmed;
    } else {
      ++report.never_observed;
    }
    report.objects.push_back(entry);
  }
  report.not_in_plan.reserve(state.elements.size());
  for (const auto& [number, element] : state.elements) report.not_in_plan.push_back(&element);
  return report;
}

const char* to_string(AsBuiltStatus status) {
  switch (status) {
    case AsBuiltStatus::moved:
      return "moved";
    case AsBuiltStatus::confirmed:
      return "confirmed";
    case AsBuiltStatus::never_observed:
      return "never_observed";
  }
  return "never_observed";
}

}  // namespace wm::world
