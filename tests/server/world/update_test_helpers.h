#pragma once

// Observations and rules answers the world update's tests share.

#include <Eigen/Core>
#include <initializer_list>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "server/world/update.h"

namespace wm::world::update_test_helpers {

inline Observation observe(std::initializer_list<std::pair<Eigen::Vector2d, Eigen::Vector2d>> segments,
                           const WorldOptions& o) {
  Observation obs;
  obs.observer = "robot";
  for (const auto& [a, b] : segments) {
    auto s = fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
    s.line.cov = midpoint_line_cov(s, o.default_offset_sigma_m, o.default_angle_sigma_rad);
    obs.segments.push_back({s});
  }
  return obs;
}

// Answers a fixed action, and records what the rules were asked.
struct FixedRules {
  std::string action;
  std::vector<rules::DecisionQuery> asked;
  rules::Decision operator()(const rules::DecisionQuery& q) {
    asked.push_back(q);
    return {action, "test_rule", "because the test says so", false};
  }
};

// Answers `merge` to scan lines and `join_action` to the maintenance question (origin "element").
struct JoiningRules {
  std::string join_action = "merge";
  std::vector<rules::DecisionQuery> asked;
  rules::Decision operator()(const rules::DecisionQuery& q) {
    asked.push_back(q);
    if (q.origin == "element") return {join_action, "elements_merged", "one wall", false};
    return {q.element_id ? "merge" : "add", "test_rule", "because", false};
  }
};

// One segment seen by a sensor at `viewpoint` (its facing set) with the midpoint-form σ a pose of that quality
// gives; `facing` false leaves the facing unknown, as for a posted segment.
inline Observation view_from(Eigen::Vector2d a, Eigen::Vector2d b, Eigen::Vector2d viewpoint, double offset_sigma_m,
                             double angle_sigma_rad, bool facing = true) {
  Observation obs;
  obs.observer = "robot";
  obs.origin = "scan";
  auto s = fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
  s.line.cov = midpoint_line_cov(s, offset_sigma_m, angle_sigma_rad);
  obs.segments.push_back({s, facing ? std::optional<double>(facing_toward(s, viewpoint)) : std::nullopt});
  return obs;
}

}  // namespace wm::world::update_test_helpers
