#pragma once

#include <functional>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "rules/engine.h"
#include "server/world/world_state.h"

namespace wm::world {

/// One posted segment after validation: the observed segment in the world frame.
struct ObservedSegment {
  fusion::LineSegment segment;
};

/// A batch of segments from one request.
struct Observation {
  std::string observer;           // e.g. robot-1
  std::string source = "client";  // client | scan | grid
  double stamp_s = 0.0;
  std::vector<ObservedSegment> segments;
};

/// What the knowledge base decided for one segment and what the server did with it.
struct DecisionRecord {
  std::int64_t seq = 0;              // global decision sequence number
  std::int64_t observation_seq = 0;  // the request it belongs to
  std::int64_t index = 0;            // position of the segment in the request
  std::string action;
  std::string rule;
  std::string explanation;
  std::optional<std::string> element;  // element or edge id the decision is about
  std::optional<std::string> object;   // CAD object, when one is involved
  std::optional<double> mahalanobis_sq;
  bool fallback = false;
  std::string observer;
  Eigen::Vector2d p0 = Eigen::Vector2d::Zero();  // the observed segment [m]
  Eigen::Vector2d p1 = Eigen::Vector2d::Zero();
};

/// The new state and everything that changed, so the store writes only those rows.
struct UpdateResult {
  WorldState state;
  std::vector<DecisionRecord> decisions;
  std::set<std::int64_t> changed_elements;  // element numbers inserted or updated
  std::set<std::size_t> changed_objects;    // indices into state.objects
};

using Decide = std::function<rules::Decision(const rules::DecisionQuery&)>;

/// Matches each segment in order against the current map (a-priori edges and elements), asks `decide`,
/// and applies the action: delete (count a confirmation), merge (Kalman fusion into an element),
/// rigid_adjust (EKF on the object's pose), add (new element). An action the server cannot apply to the
/// match (merge into a CAD edge, rigid_adjust without an object, an unknown action) becomes the documented
/// fallback: add, with fallback = true. `current` is not changed.
UpdateResult apply_observation(const WorldState& current, const Observation& observation, std::int64_t observation_seq,
                               const WorldOptions& options, const Decide& decide);

/// Replaces the floor plan; observed elements stay. @throw std::invalid_argument on geometry fusion rejects.
UpdateResult apply_floor_plan(const WorldState& current, const apriori::FloorPlan& plan, const WorldOptions& options);

}  // namespace wm::world
