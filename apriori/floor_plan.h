#pragma once

#include <Eigen/Core>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fusion/geometry/pose2d.h"
#include "fusion/kalman/rigid_object.h"

namespace wm::apriori {

/// A floor plan that failed validation. path() names the offending field, e.g. "objects[2].pose.theta".
class FloorPlanError : public std::runtime_error {
 public:
  FloorPlanError(std::string path, const std::string& message)
      : std::runtime_error(path.empty() ? message : path + ": " + message), path_(std::move(path)) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// One object of the CAD plan: a wall, a table, a door... Geometry is in the object's own frame and
/// `pose` places it in the world, so a rigid object keeps its shape when its pose changes.
struct PlanObject {
  std::string id;
  std::string kind;
  std::vector<std::string> attributes;  // free atoms; the shipped rules know `solid`, `not_deformable`
  fusion::Pose2D pose;
  std::optional<Eigen::Matrix3d> pose_cov;              // over (x [m], y [m], θ [rad]); nullopt = server default
  std::vector<std::vector<Eigen::Vector2d>> polylines;  // open polylines [m], object frame
  std::vector<Eigen::Vector2d> polygon;                 // closed outline [m], object frame (may be empty)

  bool has_attribute(std::string_view attribute) const;
  /// Edges in the object frame: consecutive polyline points, then the polygon's sides (closed).
  std::vector<fusion::LocalEdge> edges() const;
};

/// The a-priori floor plan. Invariant after parsing: object ids unique, every object has at least one edge.
struct FloorPlan {
  std::string name;
  std::vector<PlanObject> objects;
};

/// Limits applied when validating a plan; absurd values are rejected, never stored.
struct FloorPlanLimits {
  double max_abs_coordinate_m = 1.0e5;
  std::size_t max_objects = 100000;
  std::size_t max_points_per_object = 100000;
  std::size_t max_id_length = 128;
};

/// Parses and validates a JSON floor plan: {"name", "units", "objects": [{"id", "kind", "attributes",
/// "pose": {"x", "y", "theta"}, "segments" (open polylines) or "polygon" (closed), in the object's frame}]}.
/// "units" may be "m", "cm" or "mm"; coordinates are converted to metres.
/// @throw FloorPlanError with the path of the first bad field.
FloorPlan parse_floor_plan_json(std::string_view text, const FloorPlanLimits& limits = {});

/// The canonical JSON text of a plan (units "m"); parse_floor_plan_json(to_json_text(p)) == p exactly.
std::string to_json_text(const FloorPlan& plan);

}  // namespace wm::apriori
