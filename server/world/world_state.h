#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "apriori/floor_plan.h"
#include "apriori/geo/georeference.h"
#include "fusion/geometry/line.h"
#include "fusion/geometry/similarity2d.h"
#include "fusion/kalman/line_map.h"
#include "fusion/kalman/rigid_object.h"
#include "fusion/kalman/segment_moments.h"
#include "server/world/cow_map.h"
#include "server/world/spatial_hash.h"

namespace wm::world {

/// How lines of the grid line extractor (origin "grid") meet the elements that scans or a client made. The grid
/// knows a surface only to its cells (and a band fitted near a corner may lean by a degree), while those elements
/// lie within a centimetre or two of theirs, so a grid line never moves them: a merge takes in its extent, not its
/// line, and it bounds the ends of elements that run past it.
struct GridLineMatchOptions {
  /// A grid line lies on such an element when their directions differ by at most on_element_angle_rad, the grid
  /// line overlaps the element's extent, and both its ends are within on_element_offset_m of the element's line:
  /// two cells of the default 5 cm grid [m], [rad].
  double on_element_offset_m = 0.10;
  double on_element_angle_rad = 0.035;  // 2°
  /// A merge takes in the grid line's extent only where the grid line is within extend_offset_m of the element's
  /// line: one cell, so that an element is not carried along its own direction past where its wall turns away [m].
  double extend_offset_m = 0.05;
  /// An element whose end runs past the line of an element the grid's lines confirmed, merged into or became (a
  /// surface the grid saw), crossing it at min_crossing_angle_rad or more within on_element_offset_m of its extent,
  /// by at least min_corner_cut_m and at most max_corner_cut_m (three cells), is cut back to that line [m], [rad].
  double max_corner_cut_m = 0.15;
  double min_corner_cut_m = 0.02;
  double min_crossing_angle_rad = 0.5236;  // 30°
};

/// Numbers the world model uses when a request does not give them. Validated once by the config reader.
struct WorldOptions {
  fusion::MatchOptions match;
  /// The floor under a fused element's uncertainty (midpoint form): what a wall is known to after many views from
  /// poses that share their error: no better than the heading σ replays post (0.0087 rad, 0.5°). 0.0044 left
  /// calibration at 0.84 on Freiburg-079 once elements were refitted to their moments; 0.007 left it at 0.853 once
  /// single tilted views were joined into their walls as pieces (0.866 with 0.0087).
  fusion::FusionOptions fusion{0.01, 0.0087};
  /// Joins of two elements into one (asked of the rules) after one change of an element, at most.
  std::size_t max_joins_per_change = 16;
  /// When an element lies on a grown one: both are fused estimates whose directions are known to the covariance
  /// floor, so a fixed 5° floor on the direction and the same offsets as for scan lines.
  fusion::MatchOptions join{3.0, 0.03, 0.087, 0.10, false};
  /// A view of a rigid object's edge may run past the edge's ends by this share of its own length, beyond the gap
  /// and the object's own uncertainty: a far view that takes in a corner's returns runs a little past it (a table
  /// side seen from 20 m ran 17 cm past its corner and became an element of its own), while a wall the object
  /// stands against runs far past it.
  double rigid_overrun_share = 0.2;
  /// An element may only take in an observation (or another element) while everything it was built from stays
  /// this close to one straight line (RMS across it) [m]: what a wall seen with the poses' error spreads to.
  double max_straightness_rms_m = 0.05;
  /// ... unless the view's own uncertainty spreads it more: a view posted with a pose σ of 3 cm / 0.5° lies
  /// anywhere within a few cm across its midpoint and turns by 0.5°, which over 17 m is 4 cm RMS by itself. The
  /// allowance is this many σ of that spread (offset at the view's middle, and σφ·L/√12 from its direction), so
  /// the straightness asks no more of a noisy robot's views than its pose can give, and no less of a good one's.
  double straightness_sigmas = 2.5;
  /// Two elements may be joined while together they lie within this many times the RMS scatter of the less
  /// straight one (or max_straightness_rms_m): two sets with the scatter of noisy views, a few cm apart.
  double join_scatter_factor = 1.5;
  /// A merged view whose direction differs from the element's fused line by more than tilted_view_sigmas of its own
  /// direction σ stretches the element only where it runs within tilted_view_offset_m of that line [m]: a far view
  /// across a shallow bend otherwise carries the element past the corner along the next facet. A merged view whose
  /// end lies within tilted_view_offset_m of another element's line (and nearer to it) stretches the element only up
  /// to where the two lines cross.
  double tilted_view_sigmas = 2.0;
  double tilted_view_offset_m = 0.03;
  /// Two elements whose lines cross at between corner_min_angle_rad and corner_max_angle_rad are two facets of a
  /// bend: neither runs on past the corner along the other, as long as that part lies within
  /// corner_overshoot_offset_m of the other's line [m] (further off it is a wall of its own). Under 3° the crossing
  /// is too uncertain to cut at (1 cm across is 19 cm along); over 30° the corner is one the scan lines split at.
  double corner_min_angle_rad = 3.0 * std::numbers::pi / 180.0;
  double corner_max_angle_rad = 30.0 * std::numbers::pi / 180.0;
  double corner_overshoot_offset_m = 0.05;
  /// Elements seen from opposite sides (Element::facing_rad) are the two faces of a wall, kept apart, unless they
  /// lie this close to each other where they overlap [m]: then they are one thin surface (a partition, a board, a
  /// wall drawn as a single line) and are joined into one element that faces both ways.
  double thin_surface_m = 0.03;
  /// Uncertainty of a posted segment without "cov": σ across the line at the segment's midpoint [m] and σ of
  /// its direction [rad]. Stated at the midpoint because a plain diagonal (ρ, φ) covariance would be wrong for
  /// any segment far from the origin (ρ and φ are correlated through the lever arm); see midpoint_line_cov.
  double default_offset_sigma_m = 0.01;
  double default_angle_sigma_rad = 0.01;
  /// How far a drawn CAD edge may be from the built one, in the same midpoint form, added to every a-priori
  /// edge's covariance on top of its object's pose uncertainty: drawings are good but not exact.
  double apriori_offset_sigma_m = 0.02;
  double apriori_angle_sigma_rad = 0.005;
  /// Pose covariance of plan objects that do not state one (σxy = 5 cm, σθ = 0.05 rad).
  Eigen::Matrix3d default_pose_cov = Eigen::Vector3d(2.5e-3, 2.5e-3, 2.5e-3).asDiagonal();
  GridLineMatchOptions grid_lines;
};

/// A CAD object as the world model holds it: the drawing, and the body whose pose observations may move.
struct ObjectState {
  std::shared_ptr<const apriori::PlanObject> plan;  // as drawn; never changes
  fusion::RigidObject body;                         // current pose and covariance; edges from the drawing
  std::int64_t confirmations = 0;                   // observations that confirmed it unchanged
  std::int64_t adjustments = 0;                     // rigid updates applied
  std::int64_t updated_version = 0;
};

/// The id of element `number` ("e12"), as the API, the rules and the store name it.
inline std::string element_id(std::int64_t number) { return "e" + std::to_string(number); }

/// An observed element that belongs to no CAD object.
struct Element {
  std::int64_t number = 0;  // id is "e<number>"
  fusion::LineSegment segment;
  fusion::SegmentMoments moments;  // of the observed segments it was built from (not of a CAD edge it began at)
  std::int64_t support = 1;        // observations fused into it (including the first)
  /// Direction [rad] of the normal pointing to the side the wall was seen from, when known (scan lines): the two
  /// faces of a thin wall face away from each other and are never one element, however close under pose noise.
  std::optional<double> facing_rad;
  /// A thin surface seen from both sides (joined from views of either side): facing_rad is then empty, and stays so
  /// as views from one side merge into it. An empty facing_rad without it means the side is not known (posted
  /// segments, grid lines, elements stored before the side was kept), and the next view's side is taken.
  bool both_ways = false;
  std::string origin;    // of the first observation: client | scan | grid (SQL column and JSON "source")
  std::string observer;  // who sent it first, e.g. robot-1
  std::int64_t created_version = 0;
  std::int64_t updated_version = 0;
  double updated_at_unix_s = 0;  // wall-clock time of the last change (rules prune by age)

  std::string id() const { return element_id(number); }
};

/// The observed elements by number, with their spatial index kept in step. Copies share what they have not
/// changed (see CowMap), so the writer's per-request copy costs little however large the map.
class ElementTable {
 public:
  using const_iterator = CowMap<Element>::const_iterator;  // (number, element) in number order

  std::size_t size() const { return elements_.size(); }
  bool empty() const { return elements_.empty(); }
  const_iterator begin() const { return elements_.begin(); }
  const_iterator end() const { return elements_.end(); }
  const Element* find(std::int64_t number) const { return elements_.find(number); }
  /// @throw std::out_of_range when there is no such element.
  const Element& at(std::int64_t number) const { return elements_.at(number); }
  bool contains(std::int64_t number) const { return elements_.contains(number); }
  std::size_t count(std::int64_t number) const { return elements_.count(number); }

  /// Inserts or replaces the element of `element.number` (> 0). @throw std::out_of_range otherwise.
  void put(Element element);
  bool erase(std::int64_t number);
  void clear();
  /// Numbers of every element whose segment's box overlaps `box`, and perhaps a few more (callers test the
  /// geometry). Sorted.
  std::vector<std::int64_t> near(const Box& box) const { return index_.query(box); }

 private:
  CowMap<Element> elements_;
  SpatialHash index_;
};

/// The CAD objects in plan order, with an index by id and a spatial index of their edges in the world frame (as
/// posed now). Shares unchanged objects between copies like ElementTable.
class ObjectTable {
 public:
  class const_iterator {
   public:
    const_iterator(const CowMap<ObjectState>* map, std::size_t index) : map_(map), index_(index) {}
    const ObjectState& operator*() const { return map_->at(static_cast<std::int64_t>(index_)); }
    const ObjectState* operator->() const { return &**this; }
    const_iterator& operator++() {
      ++index_;
      return *this;
    }
    bool operator==(const const_iterator& other) const { return index_ == other.index_; }
    bool operator!=(const const_iterator& other) const { return index_ != other.index_; }

   private:
    const CowMap<ObjectState>* map_;
    std::size_t index_;
  };

  ObjectTable() = default;
  /// @throw std::invalid_argument when two objects share an id or an object has 2^24 edges or more.
  explicit ObjectTable(std::vector<ObjectState> objects);

  std::size_t size() const { return objects_.size(); }
  bool empty() const { return objects_.empty(); }
  const_iterator begin() const { return {&objects_, 0}; }
  const_iterator end() const { return {&objects_, objects_.size()}; }
  /// @throw std::out_of_range for an index past the end.
  const ObjectState& at(std::size_t index) const { return objects_.at(static_cast<std::int64_t>(index)); }
  const ObjectState& operator[](std::size_t index) const { return at(index); }
  std::optional<std::size_t> index_of(const std::string& id) const;

  /// Replaces object `index` (same plan object, e.g. a new pose or counters); re-indexes its edges if it moved.
  /// @throw std::out_of_range for an index past the end, std::invalid_argument for a different plan object.
  void put(std::size_t index, ObjectState object);
  /// (object index, edge index) of every edge whose box overlaps `box`, and perhaps a few more. Sorted.
  std::vector<std::pair<std::size_t, std::size_t>> edges_near(const Box& box) const;
  /// (object index, edge index) of every edge within about `reach` of the segment (its cells, not its bounding box),
  /// and perhaps a few more. Sorted.
  std::vector<std::pair<std::size_t, std::size_t>> edges_near(const fusion::LineSegment& segment, double reach) const;

 private:
  CowMap<ObjectState> objects_;
  std::shared_ptr<const std::unordered_map<std::string, std::size_t>> by_id_;
  SpatialHash edges_;
};

/// The whole mutable world model. Copied by the single writer, changed, then published as an immutable
/// snapshot, so readers never see half an update; the copy shares everything unchanged.
struct WorldState {
  std::int64_t version = 0;  // increases by one per applied request
  std::string plan_name;
  /// Where the plan's drawing frame sits in the world; every object's pose and edges are placed through it.
  fusion::Similarity2D placement;
  Eigen::Matrix4d placement_cov = Eigen::Matrix4d::Zero();  // over (x, y, θ, scale); zero for "as drawn"
  /// The world frame on the Earth, when known (the GeoJSON export is in WGS 84 then).
  std::optional<apriori::Georeference> georeference;
  ObjectTable objects;
  ElementTable elements;
  std::int64_t next_element_number = 1;
  std::int64_t last_observation_seq = 0;
  std::int64_t last_decision_seq = 0;

  const ObjectState* find_object(const std::string& id) const;
  const Element* find_element(const std::string& id) const;
  /// Parses "e<number>"; nullopt for anything else.
  static std::optional<std::int64_t> element_number(const std::string& id);
};

/// What a box of the map shows: the objects with an edge in it (plan order) and the elements with a point in it
/// (number order). Costs what the box holds, through the spatial indexes.
struct MapExcerpt {
  std::vector<std::size_t> objects;
  std::vector<std::int64_t> elements;
};
MapExcerpt map_excerpt(const WorldState& state, const Box& box);

/// Builds the object states of a plan, placed in the world by `placement` (poses and edges as drawn, then placed).
/// @throw std::invalid_argument from fusion on bad geometry.
std::vector<ObjectState> make_objects(const apriori::FloorPlan& plan, const WorldOptions& options, std::int64_t version,
                                      const fusion::Similarity2D& placement = {});

/// An object moved from one placement of the plan to another: its pose relative to the drawing (a rigid adjustment
/// included) is kept, its edges take the new scale, its covariance turns with it.
ObjectState replaced(const ObjectState& object, const fusion::Similarity2D& from, const fusion::Similarity2D& to);

/// (ρ, φ) covariance of a line known to σ_offset [m] across the segment's midpoint and σ_angle [rad] in
/// direction: J diag(σ_offset², σ_angle²) Jᵀ with J = [[1, t_mid], [0, 1]], t_mid the midpoint's coordinate
/// along the line (∂ρ/∂φ at a fixed midpoint).
Eigen::Matrix2d midpoint_line_cov(const fusion::LineSegment& segment, double sigma_offset_m, double sigma_angle_rad);

/// The CAD drawing's own uncertainty for edge k of an object (midpoint form of the options above).
Eigen::Matrix2d apriori_edge_noise(const ObjectState& object, std::size_t k, const WorldOptions& options);
/// Edge k of an object in the world frame, with pose uncertainty and drawing noise in its covariance.
fusion::LineSegment apriori_edge(const ObjectState& object, std::size_t k, const WorldOptions& options);

/// Edge id as the API names it: "<object>/<k>".
std::string edge_id(const std::string& object_id, std::size_t k);

}  // namespace wm::world
