#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "apriori/floor_plan.h"
#include "fusion/geometry/line.h"
#include "fusion/kalman/line_map.h"
#include "fusion/kalman/rigid_object.h"

namespace wm::world {

/// Numbers the world model uses when a request does not give them. Validated once by the config reader.
struct WorldOptions {
  fusion::MatchOptions match;
  /// (ρ, φ) covariance of a posted segment without "cov": σρ = 1 cm, σφ = 0.01 rad.
  Eigen::Matrix2d default_primitive_cov = Eigen::Vector2d(1e-4, 1e-4).asDiagonal();
  /// How far a drawn CAD edge may be from the built one, added to every a-priori edge's covariance
  /// (σρ = 2 cm, σφ = 0.01 rad): drawings are good but not exact.
  Eigen::Matrix2d apriori_edge_noise = Eigen::Vector2d(4e-4, 1e-4).asDiagonal();
  /// Pose covariance of plan objects that do not state one (σxy = 5 cm, σθ = 0.05 rad).
  Eigen::Matrix3d default_pose_cov = Eigen::Vector3d(2.5e-3, 2.5e-3, 2.5e-3).asDiagonal();
};

/// A CAD object as the world model holds it: the drawing, and the body whose pose observations may move.
struct ObjectState {
  std::shared_ptr<const apriori::PlanObject> plan;  // as drawn; never changes
  fusion::RigidObject body;                         // current pose and covariance; edges from the drawing
  std::int64_t confirmations = 0;                   // observations that confirmed it unchanged
  std::int64_t adjustments = 0;                     // rigid updates applied
  std::int64_t updated_version = 0;
};

/// An observed element that belongs to no CAD object.
struct Element {
  std::int64_t number = 0;  // id is "e<number>"
  fusion::LineSegment segment;
  std::int64_t support = 1;  // observations fused into it (including the first)
  std::string source;        // origin of the first observation: client | scan | grid
  std::string observer;      // who sent it first, e.g. robot-1
  std::int64_t created_version = 0;
  std::int64_t updated_version = 0;

  std::string id() const { return "e" + std::to_string(number); }
};

/// The whole mutable world model. Copied by the single writer, changed, then published as an immutable
/// snapshot, so readers never see half an update.
struct WorldState {
  std::int64_t version = 0;  // increases by one per applied request
  std::string plan_name;
  std::vector<ObjectState> objects;  // in plan order
  std::unordered_map<std::string, std::size_t> object_index;
  std::map<std::int64_t, Element> elements;  // by number
  std::int64_t next_element_number = 1;
  std::int64_t last_observation_seq = 0;
  std::int64_t last_decision_seq = 0;

  const ObjectState* find_object(const std::string& id) const;
  const Element* find_element(const std::string& id) const;
  /// Parses "e<number>"; nullopt for anything else.
  static std::optional<std::int64_t> element_number(const std::string& id);
};

/// Builds the object states of a plan (poses as drawn). @throw std::invalid_argument from fusion on bad geometry.
std::vector<ObjectState> make_objects(const apriori::FloorPlan& plan, const WorldOptions& options, std::int64_t version);
void rebuild_object_index(WorldState& state);

/// Edge id as the API names it: "<object>/<k>".
std::string edge_id(const std::string& object_id, std::size_t k);

}  // namespace wm::world
