#pragma once

// Shared by the files of the world update (update.cpp: matching and the decision loop; update_joins.cpp: joining
// elements; update_corners.cpp: elements cut back at shallow corners; update_rigid.cpp: rigid objects and the shape
// search; update_grid_lines.cpp: grid lines). Not part of the module's interface.

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "server/world/update.h"

namespace wm::world::update_internal {

// Candidates farther than this (box to box, plus the gap allowance) cannot pass the segment gate of any sane
// tolerance; it only saves work.
inline constexpr double kCandidateMarginM = 1.0;

// Where a matching candidate came from: an edge of a CAD object or an observed element.
struct CandidateRef {
  std::optional<std::size_t> object;  // index into state.objects
  std::size_t edge = 0;
  std::int64_t element = 0;  // element number when object is empty
};

// How far (box to box) a candidate may be and still be worth the gate.
inline double candidate_margin(const fusion::MatchOptions& match) { return kCandidateMarginM + match.max_gap_m; }

// Objects the server moves rigidly when the rules say so (the shipped rules: rigid_adjust on a match).
inline bool is_rigid(const ObjectState& object) { return object.plan->has_attribute("not_deformable"); }

// Whether element `e` was made from grid lines alone, or from scans or by a client.
inline bool made_by_grid(const Element& e) { return e.origin == "grid"; }

struct Candidates {
  std::vector<fusion::LineSegment> segments;
  std::vector<CandidateRef> refs;
};

// Rigid objects found again by their shape in one observation: per segment the object and edge it lies on, and
// the pose each object was found at.
struct FoundByShape {
  std::vector<std::optional<CandidateRef>> ref;
  std::map<std::size_t, fusion::Pose2D> pose;
};

// The lines of one observation the rules sent to rigid_adjust one object: applied together, once.
struct PendingRigid {
  std::vector<fusion::EdgeObservation> lines;
  std::vector<std::size_t> records;   // into result.decisions, one per line
  std::vector<std::size_t> segments;  // into observation.segments, one per line
  bool by_shape = false;              // some of them were found by the object's shape
};

// What can match `seen`: the CAD edges and elements whose boxes come near it (the gate tolerances stay well
// inside the margin).
Candidates collect_candidates(const WorldState& state, const fusion::LineSegment& seen,
                              const std::optional<double>& seen_facing, const WorldOptions& options);

// Whether two segments lie end to end rather than over each other: less than half of the shorter one's extent,
// projected on the longer one's line, falls within the longer one, or, when the shorter runs on past one of the
// longer one's ends, less than three times the shorter one's offset from that line. Two surfaces seen from one side
// cannot lie over each other a few cm apart (the nearer hides the farther) beyond what an oblique view through the gap
// at the nearer one's end shows of the farther (offset · tan θ), so parts that overlap more are views of one surface,
// however far one of them is off; parts end to end may be two (a depth step).
bool end_to_end(const fusion::LineSegment& a, const fusion::LineSegment& b);

// Whether two parts that lie end to end are two surfaces side by side (a depth step at a door frame, a pilaster's
// face): the shorter one's mass (the views it was built from) lies farther than `allowance_m` RMS from the longer
// one's line. The RMS of the two together weighs each by its length, so a short wall 15 cm beside a long one barely
// shows in it, and a line fitted to both turns toward the short one and hides half of its offset.
// The overlap argument holds only when both were seen from one side: an element that faces both ways (a thin wall
// joined from its two sides) has an extent seen partly from the other side, over which a surface in front of it may
// well lie; then `one_side` is false and parts that overlap are tested too.
bool side_by_side(const fusion::SegmentMoments& a, const fusion::LineSegment& a_segment,
                  const fusion::SegmentMoments& b, const fusion::LineSegment& b_segment, double allowance_m,
                  bool one_side = true);

// How far from one straight line (RMS) an element and a new view of it may lie together: the fixed allowance, or
// WorldOptions::straightness_sigmas σ of the spread the view's own covariance gives (across its middle, and its
// direction's σ over its length), whichever is larger.
double straightness_allowance_m(const fusion::LineSegment& seen, const WorldOptions& options);

std::vector<double> line_numbers(const fusion::LineFeature& line);

std::vector<double> pose_numbers(const fusion::RigidObject& body);

// The segment a decision is about, as the log keeps it.
void record_observed(DecisionRecord& record, const fusion::LineSegment& segment);

// Takes element `number` (in the state) out of the map with a prune decision of `rule`, and returns that decision
// (the last of result.decisions) for the caller to add to.
DecisionRecord& remove_element(UpdateResult& result, std::int64_t number, std::string rule, std::string explanation,
                               const std::string& observer, std::int64_t observation_seq);

// Who cut an element and when: the observation a trim decision belongs to.
struct TrimSource {
  std::int64_t observation_seq = 0;
  std::string observer, origin, sensor;
  std::optional<double> at_unix_s;  // the element's updated_at_unix_s, when the cut comes with a received request
};

// Cuts element `number` (in result.state, whose version is already the new one) to the extent `kept` of its own
// line, with a trim decision of `rule` (before/after: the old and new endpoints [x0, y0, x1, y1]), and returns that
// decision (the last of result.decisions) for the caller to add to.
DecisionRecord& trim_element(UpdateResult& result, std::int64_t number, const fusion::LineSegment& kept,
                             std::string rule, std::string explanation, const TrimSource& source);

// The element's line after it took in more views: the Kalman update gives the covariance (floored, see
// WorldOptions::fusion) and the extent; the line itself is the best fit of everything the element was built from.
// The views' own scatter across the line (the pose error they do not share) floors the offset uncertainty at the
// midpoint, so a view as far off as the ones already taken in still matches.
fusion::LineSegment fused_and_refit(const fusion::LineSegment& fused, const fusion::SegmentMoments& moments);

void make_fallback(DecisionRecord& record, std::string_view answered, const std::string& why);

// After element `number` grew, other elements may now lie on it: two views of one wall that no single observation
// connected before. Each such neighbour (best first) is joined into it if the rules say merge (join_into); anything
// else leaves both. A neighbour that passes only as a piece of the grown element (lies_within) comes after every
// gated one. When the grown element is itself a piece of a longer one, it is joined into that one instead, and
// nothing more is asked for it.
void join_neighbours(UpdateResult& result, std::int64_t number, const Observation& observation,
                     std::int64_t observation_seq, const WorldOptions& options, const Decide& decide);

// Where segment `a` runs through its crossing with `b`'s line and on past it along `b` (a shallow bend between
// WorldOptions::corner_min_angle_rad and corner_max_angle_rad, `b` running on from the corner the way a's shorter
// side goes, further than back, and covering it, that side at least 2 cm long and within corner_overshoot_offset_m
// of b's line): what `a` keeps, up to the corner. nullopt when a does not run past a corner with b.
struct CornerCut {
  fusion::LineSegment kept;
  Eigen::Vector2d corner;
  double overshoot_m = 0;
  double angle_rad = 0;
};
std::optional<CornerCut> cut_past_corner(const fusion::LineSegment& a, const fusion::LineSegment& b,
                                         const WorldOptions& options);

// The extent of element `number` after a merge grew it to `grown`: not past a shallow corner with a neighbour
// (cut_past_corner), and never less than it had before (`kept`, on grown's line: what it held is cut_at_corners'
// to cut, with a decision).
fusion::LineSegment stop_at_corners(const WorldState& state, std::int64_t number, const std::pair<double, double>& kept,
                                    fusion::LineSegment grown, const WorldOptions& options);

// After element `number` grew (a merge, an add, a join into it): it and its neighbours are cut back where one runs
// past a shallow corner along the other (cut_past_corner), each cut a trim decision of rule corner_cut whose
// matched_element is the other. Elements a client posted are not cut (as the grid trim leaves them), and two
// elements seen from opposite sides are not each other's corner (the two faces of a wall). A view that takes in a few
// returns past a corner of two facets a few degrees apart, or an element made before its neighbour was seen, otherwise
// runs on along the next facet.
void cut_at_corners(UpdateResult& result, std::int64_t number, const Observation& observation,
                    std::int64_t observation_seq, const WorldOptions& options);

// A rigid object carried beyond its gate leaves its views unmatched (or matched to it at the old pose, the wrong
// way). Several such views of one observation near a rigid object that its edges explain after one rigid
// transform (fusion::find_by_shape: lengths and extents included, so the walls beside it do not count) are taken
// as views of it. Only objects within kShapeSearchM of the observation, only when at least one of the views is
// unmatched, and only views that match nothing else.
FoundByShape find_moved_objects(const WorldState& state, const Observation& observation, const WorldOptions& options);

// A new element from an observed segment (the add action); its number.
std::int64_t add_element(UpdateResult& result, const ObservedSegment& seen, const Observation& observation);

// One joint update of object `index` from every line the rules sent to it (one edge alone fixes only its normal and
// the turn). When the object was found by its shape, its covariance first widens to cover the move (it was
// carried) and the iteration starts at the pose found. If the update fails, each line becomes the fallback add.
void apply_rigid(UpdateResult& result, std::size_t index, const PendingRigid& pending, const FoundByShape& found,
                 const Observation& observation, std::int64_t observation_seq, const WorldOptions& options,
                 const Decide& decide);

// The element made from scans or by a client that the grid line lies on (GridLineMatchOptions), the closest (the
// larger of the grid line's end offsets); nullopt when there is none.
std::optional<std::int64_t> grid_line_on_element(const WorldState& state, const fusion::LineSegment& seen,
                                                 const GridLineMatchOptions& options);

// The stretch [t0, t1] along `line` [m] over which the segment lies within `offset_m` of it; nullopt when nowhere.
std::optional<std::pair<double, double>> stretch_within(const fusion::LineFeature& line,
                                                        const fusion::LineSegment& segment, double offset_m);

// After a grid extraction: an element cannot run on behind a surface the grid saw. Each element whose end runs past
// the line of one of `surfaces` (the elements the extraction's lines confirmed, merged into or became) near that
// surface's extent, crossing it at a real angle, is cut back to it when the part past it is short and the rest of
// the element lies on the other side (GridLineMatchOptions). Why: an element's extent is the union of its views,
// and near a corner the extreme views of a few hundred reach 5–10 cm behind the other wall; the grid trim does not
// see that, as the other wall's occupied band backs it. Each cut is a "trim" decision (rule grid_crossing_trimmed)
// with the old and new endpoints; the line, its covariance and its moments stay. Client elements are not cut.
void cut_at_grid_surfaces(UpdateResult& result, const std::set<std::int64_t>& surfaces, const Observation& observation,
                          std::int64_t observation_seq, const GridLineMatchOptions& options);

}  // namespace wm::world::update_internal
