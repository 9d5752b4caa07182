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

AsBuiltReport as_built_report(const WorldState& state, const PlanReport* evidence) {
  AsBuiltReport report;
  report.objects.reserve(state.objects.size());
  for (const auto& object : state.objects) {
    ObjectAsBuilt entry{&object, AsBuiltStatus::never_observed, std::nullopt, {}};
    if (object.adjustments > 0) entry.moved_by = displacement(object);
    report.objects.push_back(entry);
  }
  if (evidence) {
    for (const auto& verdict : evidence->verdicts)
      if (const auto index = state.objects.index_of(verdict.object_id))
        report.objects[*index].verdicts.push_back(&verdict);
  }
  for (auto& entry : report.objects) {
    const auto has = [&entry](const char* name) {
      return std::any_of(entry.verdicts.begin(), entry.verdicts.end(),
                         [name](const Verdict* v) { return v->verdict == name; });
    };
    // A verdict says more than adjustments, and an adjustment more than any number of confirmations.
    if (has("gone")) {
      entry.status = AsBuiltStatus::gone;
      ++report.gone;
    } else if (has("missing")) {
      entry.status = AsBuiltStatus::missing;
      ++report.missing;
    } else if (has("partly_missing")) {
      entry.status = AsBuiltStatus::partly_missing;
      ++report.partly_missing;
    } else if (entry.object->adjustments > 0) {
      entry.status = AsBuiltStatus::moved;
      ++report.moved;
    } else if (entry.object->confirmations > 0) {
      entry.status = AsBuiltStatus::confirmed;
      ++report.confirmed;
    } else {
      ++report.never_observed;
    }
  }
  report.not_in_plan.reserve(state.elements.size());
  for (const auto& [number, element] : state.elements) report.not_in_plan.push_back(&element);
  return report;
}

const char* to_string(AsBuiltStatus status) {
  switch (status) {
    case AsBuiltStatus::gone:
      return "gone";
    case AsBuiltStatus::missing:
      return "missing";
    case AsBuiltStatus::partly_missing:
      return "partly_missing";
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
