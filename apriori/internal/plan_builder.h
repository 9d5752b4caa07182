#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "apriori/floor_plan.h"
#include "apriori/import/import_report.h"
#include "fusion/geometry/pose2d.h"

namespace wm::apriori::internal {

/// A polyline in the world frame [m]; `closed` joins the last point to the first (without repeating it).
struct WorldShape {
  std::vector<Eigen::Vector2d> points;
  bool closed = false;
};

/// Throws FloorPlanError(where, ...) unless both coordinates are finite and within ±limit [m].
void check_world_point(const Eigen::Vector2d& p, double limit_m, const std::string& where);

/// The length-weighted centroid of the shapes' edges [m] (the mean of their points when all edges are shorter than
/// 1e-12 m). @throw std::invalid_argument when there is no point at all.
Eigen::Vector2d centroid(const std::vector<WorldShape>& shapes);

/// Collects imported objects into a FloorPlan that satisfies the invariants of parse_floor_plan_json: unique ids,
/// attributes as atoms, no edge shorter than 1e-6 m, at least one edge per object, the limits.
class PlanBuilder {
 public:
  PlanBuilder(std::string name, const FloorPlanLimits& limits);

  /// Adds one object whose geometry is given in the world frame. With `pose` the object frame is that pose (block
  /// inserts, models); without, it is the shapes' centroid with θ = 0, so that a rigid object turns about its
  /// middle. Points closer than 1e-6 m to their predecessor are dropped, and shapes left without an edge.
  /// A single closed shape becomes the object's polygon; otherwise every shape is a polyline (closed ones repeat
  /// their first point). `id_hint` is made unique (suffix "-2", "-3", ...) and safe (no '/', no control
  /// characters, at most limits.max_id_length characters).
  /// @return the id given, or nullopt when nothing with an edge was left (the caller counts it as degenerate).
  /// @throw FloorPlanError(where, ...) for too many objects or points, or a point beyond the limits.
  std::optional<std::string> add(const std::string& id_hint, const std::string& kind,
                                 const std::vector<std::string>& attributes, const std::vector<WorldShape>& shapes,
                                 const std::optional<fusion::Pose2D>& pose, const std::string& where);

  std::size_t size() const { return plan_.objects.size(); }
  const std::optional<Extent>& extent() const { return extent_; }

  /// The plan, checked once more by its own JSON round trip (parse_floor_plan_json(to_json_text(plan), limits)),
  /// so that an imported plan is always one the JSON path would accept and store.
  /// @throw FloorPlanError naming the object when that check fails.
  FloorPlan finish() &&;

 private:
  std::string unique_id(const std::string& hint);

  FloorPlan plan_;
  FloorPlanLimits limits_;
  std::set<std::string> ids_;
  std::optional<Extent> extent_;
};

}  // namespace wm::apriori::internal
