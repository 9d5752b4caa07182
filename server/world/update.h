#pragma once

#include <functional>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "rules/action.h"
#include "rules/types.h"
#include "server/world/world_state.h"

namespace wm::world {

/// One posted segment after validation: the observed segment in the world frame.
struct ObservedSegment {
  ObservedSegment(fusion::LineSegment seen, std::optional<double> facing = std::nullopt)  // NOLINT: {segment}
      : segment(std::move(seen)), facing_rad(facing) {}

  fusion::LineSegment segment;
  /// Direction [rad] of the line's normal toward the sensor that saw it (see facing_toward); none when not known
  /// (posted segments, grid lines).
  std::optional<double> facing_rad;
  /// The element whose line this view continues (world::scan_continuations): it says how far that line runs, not
  /// where it lies, so it is matched to that element only and a merge takes in its extent, not its line; any other
  /// answer of the rules is not applied.
  std::optional<std::int64_t> continues;
};

/// What every decision about a continuation of element `number` (ObservedSegment::continues) says of it, in its
/// explanation: "a continuation of eN through sparse grazing returns".
std::string continuation_note(std::int64_t number);

/// The direction [rad] of the normal of `segment`'s line that points to `viewpoint`'s side: which face of a wall a
/// sensor at `viewpoint` saw.
double facing_toward(const fusion::LineSegment& segment, const Eigen::Vector2d& viewpoint);

/// Whether two faces can be one surface: true unless both are known and point away from each other (more than
/// 90° apart).
bool faces_agree(const std::optional<double>& a, const std::optional<double>& b);

/// A batch of segments from one request. Naming throughout world/ and storage/: `observer` is the robot (or
/// client) that saw it, `origin` how the segments were made: posted by a client, extracted from a scan or from
/// the grid. (The JSON field "source" that clients send is the observer; the codec maps it.)
struct Observation {
  std::string observer;            // e.g. robot-1
  std::string origin = "client";   // client | scan | grid
  std::string sensor = "unknown";  // laser | sonar | ... (what observation_sensor/1 tells the rules)
  double stamp_s = 0.0;
  double received_at_unix_s = 0.0;  // server wall clock
  std::vector<ObservedSegment> segments;
};

/// What the knowledge base decided for one segment and what the server did with it.
struct DecisionRecord {
  std::int64_t seq = 0;                       // global decision sequence number
  std::int64_t observation_seq = 0;           // the request it belongs to
  std::int64_t index = 0;                     // position of the segment in the request
  rules::Action action = rules::Action::add;  // what the server did (after any fallback)
  std::string rule;
  std::string explanation;
  std::optional<std::string> element;  // element or edge id the decision is about
  std::optional<std::string> object;   // CAD object, when one is involved
  std::optional<double> mahalanobis_sq;
  /// What the matcher found (element/edge id and its CAD object), kept apart from `element`, which names
  /// the element the action produced (e.g. the new element of an add).
  std::optional<std::string> matched_element, matched_object;
  bool fallback = false;
  std::string observer;
  std::string origin = "client";  // client | scan | grid
  std::string sensor = "unknown";
  Eigen::Vector2d p0 = Eigen::Vector2d::Zero();  // the observed segment [m]
  Eigen::Vector2d p1 = Eigen::Vector2d::Zero();
  double rho_m = 0, phi_rad = 0;  // the observed line and its covariance
  Eigen::Matrix2d observed_cov = Eigen::Matrix2d::Zero();
  /// What the action changed, for explanations: merge → the element's [ρ, φ, C(2×2 row-major)];
  /// rigid_adjust → the object's [x, y, θ, C(3×3 row-major)] before and after the one joint update of every line
  /// of the request sent to it (the same numbers on each of those decisions); trim → the element's endpoints
  /// [x0, y0, x1, y1]; empty otherwise.
  std::vector<double> before, after;

  /// The question the rules were asked (to re-ask it, e.g. in a dry run).
  rules::DecisionQuery query() const;
};

/// The new state and everything that changed, so the store writes only those rows.
struct UpdateResult {
  WorldState state;
  std::vector<DecisionRecord> decisions;
  std::set<std::int64_t> changed_elements;  // element numbers inserted or updated
  std::set<std::int64_t> removed_elements;  // element numbers removed (pruned)
  std::set<std::size_t> changed_objects;    // indices into state.objects
};

using Decide = std::function<rules::Decision(const rules::DecisionQuery&)>;

/// Matches each segment in order against the current map (a-priori edges and elements), asks `decide`,
/// and applies the action: confirm (wire name "delete": count a confirmation), merge (Kalman fusion into an element;
/// into a CAD edge: a new element starting from the fusion of the edge and the observation, the drawing unchanged),
/// rigid_adjust (iterated EKF on the object's pose: all the request's lines sent to one object in one joint update,
/// after the last segment), add (new element), ignore (nothing changes). A not_deformable object's edge is no
/// candidate for a line that runs past its extent (the wall beside a table). A not_deformable object carried beyond
/// its gate is found again by its shape: unmatched lines of the request near it that its edges explain after one
/// rigid transform are matched to those edges (fusion::find_by_shape), and a rigid_adjust of them starts from the
/// pose found, with the covariance widened to cover the move. Lines of origin "grid" (the grid line extractor's): one
/// that lies on an element from scans or a client (WorldOptions::grid_lines) is matched to it even outside the
/// segment gate, and a merge into such an element takes in its support and extent, not its line; after the last
/// line, an element whose end runs a little past an element the lines confirmed, merged into or became is cut back
/// to it (a trim decision, rule grid_crossing_trimmed). An action the
/// server cannot apply to the match (merge or rigid_adjust without a match, rigid_adjust on an element,
/// an unknown action) becomes the documented fallback: add, with fallback = true. `current` is not changed.
UpdateResult apply_observation(const WorldState& current, const Observation& observation, std::int64_t observation_seq,
                               const WorldOptions& options, const Decide& decide);

/// Removes the elements the rules' prune/3 named (unknown ids are skipped), each with a "prune" decision
/// record of the same observation, in `result` (so the store commits them together).
void apply_prune(UpdateResult& result, const std::vector<rules::PruneOrder>& orders, std::int64_t observation_seq,
                 const std::string& observer);

/// Replaces the floor plan (placed as the current plan is); observed elements stay.
/// @throw std::invalid_argument on geometry fusion rejects.
UpdateResult apply_floor_plan(const WorldState& current, const apriori::FloorPlan& plan, const WorldOptions& options);

/// Why a placement changes, for its decision record.
struct PlacementChange {
  fusion::Similarity2D placement;
  Eigen::Matrix4d cov = Eigen::Matrix4d::Zero();
  std::string rule;         // placed | paired | aligned | undone
  std::string explanation;  // what the decision log says
  std::string observer;     // who asked
};

/// Places the plan anew: every object keeps its pose relative to the drawing (see replaced()); one `place` decision
/// with the placement before and after ([x, y, θ, scale, C(4×4 row-major)]) as observation `observation_seq`.
UpdateResult apply_placement(const WorldState& current, const PlacementChange& change, std::int64_t observation_seq);

/// The numbers a `place` decision keeps of a placement: x, y, θ, scale, then the 4×4 covariance row-major.
std::vector<double> placement_numbers(const fusion::Similarity2D& placement, const Eigen::Matrix4d& cov);

}  // namespace wm::world
