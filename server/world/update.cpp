#include "server/world/update.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <string_view>

namespace wm::world {
namespace {

// Candidates farther than this (box to box, plus the gap allowance) cannot pass the segment gate of any sane
// tolerance; it only saves work.
constexpr double kCandidateMarginM = 1.0;

// Where a matching candidate came from: an edge of a CAD object or an observed element.
struct CandidateRef {
  std::optional<std::size_t> object;  // index into state.objects
  std::size_t edge = 0;
  std::int64_t element = 0;  // element number when object is empty
};

// How far (box to box) a candidate may be and still be worth the gate.
double candidate_margin(const fusion::MatchOptions& match) { return kCandidateMarginM + match.max_gap_m; }

// Objects the server moves rigidly when the rules say so (the shipped rules: rigid_adjust on a match).
bool is_rigid(const ObjectState& object) { return object.plan->has_attribute("not_deformable"); }

// Whether `seen` can be a view of `edge`, an edge of the rigid `object`: its ends within the edge's extent, up to
// the gap allowance plus 3σ of where the object stands along the edge. A rigid object does not stretch, so a line
// much longer than the edge, or running past its end (the wall a table stands against), is not that edge.
bool within_extent(const ObjectState& object, const fusion::LineSegment& edge, const fusion::LineSegment& seen,
                   double gap_m) {
  const Eigen::Vector2d d = edge.line.direction();
  const Eigen::Vector2d middle = 0.5 * (edge.p0() + edge.p1());
  const auto& pose = object.body.pose();
  // Along the edge, the middle moves by d·δt + d·J(middle − t)·δθ.
  const Eigen::Vector3d j(d.x(), d.y(), d.dot(Eigen::Vector2d(-(middle.y() - pose.y_m), middle.x() - pose.x_m)));
  const double slack = gap_m + 3.0 * std::sqrt(std::max(0.0, j.dot(object.body.pose_cov() * j)));
  const double ta = edge.line.coordinate_along(seen.p0()), tb = edge.line.coordinate_along(seen.p1());
  return std::min(ta, tb) >= edge.t0_m - slack && std::max(ta, tb) <= edge.t1_m + slack;
}

// How far from one straight line (RMS) an element and a new view of it may lie together: the fixed allowance, or
// WorldOptions::straightness_sigmas σ of the spread the view's own covariance gives (across its middle, and its
// direction's σ over its length), whichever is larger.
double straightness_allowance_m(const fusion::LineSegment& seen, const WorldOptions& options) {
  const double middle = 0.5 * (seen.t0_m + seen.t1_m), length = seen.length_m();
  const double spread_sq = std::max(0.0, fusion::offset_variance_at(seen.line, middle)) +
                           std::max(0.0, seen.line.cov(1, 1)) * length * length / 12.0;
  return std::max(options.max_straightness_rms_m, options.straightness_sigmas * std::sqrt(spread_sq));
}

// The same for joining two elements: each is already as straight as its views' spread let it be, so the join
// may spread WorldOptions::join_scatter_factor times as much as the less straight one, never less than the fixed
// allowance. (Their covariances would not do: the fusion floor gives every element 0.5° however good its poses.)
double join_straightness_allowance_m(const Element& a, const Element& b, const WorldOptions& options) {
  return std::max(options.max_straightness_rms_m,
                  options.join_scatter_factor * std::max(a.moments.rms_offset_m(), b.moments.rms_offset_m()));
}

struct Candidates {
  std::vector<fusion::LineSegment> segments;
  std::vector<CandidateRef> refs;
};

// What can match `seen`: the CAD edges and elements whose boxes come near it (the gate tolerances stay well
// inside the margin).
Candidates collect_candidates(const WorldState& state, const fusion::LineSegment& seen,
                              const std::optional<double>& seen_facing, const WorldOptions& options) {
  const Box near = Box::of(seen, candidate_margin(options.match));
  Candidates c;
  for (const auto& [i, k] : state.objects.edges_near(near)) {
    auto edge = apriori_edge(state.objects[i], k, options);
    if (!Box::of(edge).overlaps(near)) continue;
    if (is_rigid(state.objects[i]) && !within_extent(state.objects[i], edge, seen, options.match.max_gap_m)) continue;
    c.segments.push_back(std::move(edge));
    c.refs.push_back({i, k, 0});
  }
  const auto seen_moments = fusion::SegmentMoments::of(seen);
  const double straightness = straightness_allowance_m(seen, options);
  for (const auto number : state.elements.near(near)) {
    const Element& element = state.elements.at(number);
    if (!Box::of(element.segment).overlaps(near) || !faces_agree(element.facing_rad, seen_facing)) continue;
    // Taking `seen` in would bend the element: not the same straight wall, whatever the gate says.
    if ((element.moments + seen_moments).rms_offset_m() > straightness) continue;
    c.segments.push_back(element.segment);
    c.refs.push_back({std::nullopt, 0, number});
  }
  return c;
}

rules::DecisionQuery make_query(const WorldState& state, const Observation& observation,
                                const fusion::LineSegment& seen, const std::optional<fusion::MatchResult>& match,
                                const Candidates& candidates) {
  rules::DecisionQuery q;
  q.observer = observation.observer;
  q.origin = observation.origin;
  q.sensor = observation.sensor;
  q.rho_m = seen.line.rho_m;
  q.phi_rad = seen.line.phi_rad;
  q.length_m = seen.length_m();
  if (match) {
    const auto& ref = candidates.refs[match->index];
    if (ref.object) {
      const auto& id = state.objects[*ref.object].plan->id;
      q.element_id = edge_id(id, ref.edge);
      q.object_id = id;
    } else {
      q.element_id = element_id(ref.element);
    }
    q.mahalanobis_sq = match->mahalanobis_sq;
  }
  return q;
}

std::vector<double> line_numbers(const fusion::LineFeature& line) {
  return {line.rho_m, line.phi_rad, line.cov(0, 0), line.cov(0, 1), line.cov(1, 0), line.cov(1, 1)};
}

std::vector<double> pose_numbers(const fusion::RigidObject& body) {
  std::vector<double> v{body.pose().x_m, body.pose().y_m, body.pose().theta_rad};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) v.push_back(body.pose_cov()(r, c));
  return v;
}

// The segment a decision is about, as the log keeps it.
void record_observed(DecisionRecord& record, const fusion::LineSegment& segment) {
  record.p0 = segment.p0();
  record.p1 = segment.p1();
  record.rho_m = segment.line.rho_m;
  record.phi_rad = segment.line.phi_rad;
  record.observed_cov = segment.line.cov;
}

// Takes element `number` (in the state) out of the map with a prune decision of `rule`, and returns that decision
// (the last of result.decisions) for the caller to add to.
DecisionRecord& remove_element(UpdateResult& result, std::int64_t number, std::string rule, std::string explanation,
                               const std::string& observer, std::int64_t observation_seq) {
  WorldState& state = result.state;
  const Element& removed = state.elements.at(number);
  DecisionRecord record;
  record.seq = ++state.last_decision_seq;
  record.observation_seq = observation_seq;
  record.index = -1;  // not about a segment of the request
  record.action = rules::Action::prune;
  record.rule = std::move(rule);
  record.explanation = std::move(explanation);
  record.element = removed.id();
  record.observer = observer;
  record.origin = removed.origin;
  record_observed(record, removed.segment);
  record.before = line_numbers(removed.segment.line);
  state.elements.erase(number);
  result.changed_elements.erase(number);
  result.removed_elements.insert(number);
  result.decisions.push_back(std::move(record));
  return result.decisions.back();
}

// The element's line after it took in more views: the Kalman update gives the covariance (floored, see
// WorldOptions::fusion) and the extent; the line itself is the best fit of everything the element was built from.
// The views' own scatter across the line (the pose error they do not share) floors the offset uncertainty at the
// midpoint, so a view as far off as the ones already taken in still matches.
fusion::LineSegment fused_and_refit(const fusion::LineSegment& fused, const fusion::SegmentMoments& moments) {
  return fusion::with_covariance_floor(moments.refit(fused).value_or(fused), {moments.rms_offset_m(), 0.0});
}

void make_fallback(DecisionRecord& record, std::string_view answered, const std::string& why) {
  record.explanation = "fallback (" + why + "); rules said " + std::string(answered) + " by " + record.rule;
  record.action = rules::Action::add;
  record.rule = "fallback";
  record.fallback = true;
}

// Whether `part` is a piece of the wall `whole` stands for, whatever its own direction says: at most half as long,
// its ends projected within `max_gap_m` of the whole's extent, and the part as a whole within `band_m` RMS of its
// line (the straightness an element keeps). A view of 0.3–0.7 m tilted by a 3σ 7° lies within 3 cm RMS of its
// wall but fails the direction gate; left alone, it stays as a stub beside the wall.
bool lies_within(const Element& part, const Element& whole, double band_m, double max_gap_m) {
  const fusion::LineSegment& w = whole.segment;
  if (part.support > 1 || part.segment.length_m() > 0.5 * w.length_m()) return false;
  const Eigen::Vector2d ends[2] = {part.segment.p0(), part.segment.p1()};
  double offsets[2];
  for (int k = 0; k < 2; ++k) {
    const double t = w.line.coordinate_along(ends[k]);
    if (t < w.t0_m - max_gap_m || t > w.t1_m + max_gap_m) return false;
    offsets[k] = w.line.signed_distance(ends[k]);
  }
  // RMS distance from the line of a segment whose ends lie at offsets a and b: sqrt((a² + ab + b²) / 3).
  const double a = offsets[0], b = offsets[1];
  return (a * a + a * b + b * b) / 3.0 <= band_m * band_m;
}

// Puts "element `from` lies on element `into`" to the rules (an observation of origin "element", observer: from's
// id); a merge answer joins them: fused line, union of extents, support and moments summed, `from` removed, one
// decision logged. A `piece` (lies_within) adds its moments and support but not its line: a view whose direction
// failed the gate would make the wall's covariance claim what the view does not know. Whether they were joined.
bool join_into(UpdateResult& result, std::int64_t into, std::int64_t from, const fusion::MatchResult& match, bool piece,
               const Observation& observation, std::int64_t observation_seq, const WorldOptions& options,
               const Decide& decide) {
  WorldState& state = result.state;
  const Element& keeper = state.elements.at(into);
  const Element& other = state.elements.at(from);
  rules::DecisionQuery q;
  q.observer = other.id();
  q.origin = "element";
  q.sensor = observation.sensor;
  q.rho_m = other.segment.line.rho_m;
  q.phi_rad = other.segment.line.phi_rad;
  q.length_m = other.segment.length_m();
  q.element_id = keeper.id();
  q.mahalanobis_sq = match.mahalanobis_sq;
  const rules::Decision decision = decide(q);
  if (rules::parse_action(decision.action) != rules::Action::merge) return false;
  DecisionRecord record;
  record.seq = ++state.last_decision_seq;
  record.observation_seq = observation_seq;
  record.index = -1;  // not about a segment of the request
  record.action = rules::Action::merge;
  record.rule = decision.rule;
  record.explanation = decision.explanation;
  record.fallback = decision.fallback;
  record.element = record.matched_element = keeper.id();
  record.mahalanobis_sq = match.mahalanobis_sq;
  record.observer = observation.observer;
  record.origin = "element";
  record.sensor = observation.sensor;
  record_observed(record, other.segment);
  record.before = line_numbers(keeper.segment.line);

  Element joined = keeper;
  joined.moments += other.moments;
  joined.segment = fused_and_refit(piece ? keeper.segment : fusion::fuse(keeper.segment, other.segment, options.fusion),
                                   joined.moments);
  joined.support += other.support;
  // A thin surface seen from both sides faces both ways: views from either side match it from now on.
  joined.facing_rad = faces_agree(keeper.facing_rad, other.facing_rad)
                          ? keeper.facing_rad.has_value() ? keeper.facing_rad : other.facing_rad
                          : std::nullopt;
  joined.updated_version = state.version;
  joined.updated_at_unix_s = observation.received_at_unix_s;
  record.after = line_numbers(joined.segment.line);
  state.elements.erase(from);
  result.changed_elements.erase(from);
  result.removed_elements.insert(from);
  state.elements.put(std::move(joined));
  result.changed_elements.insert(into);
  result.decisions.push_back(std::move(record));
  return true;
}

// After element `number` grew, other elements may now lie on it: two views of one wall that no single observation
// connected before. Each such neighbour (best first) is joined into it if the rules say merge (join_into); anything
// else leaves both. A neighbour that passes only as a piece of the grown element (lies_within) comes after every
// gated one. When the grown element is itself a piece of a longer one, it is joined into that one instead, and
// nothing more is asked for it.
void join_neighbours(UpdateResult& result, std::int64_t number, const Observation& observation,
                     std::int64_t observation_seq, const WorldOptions& options, const Decide& decide) {
  WorldState& state = result.state;
  std::set<std::int64_t> declined;
  for (std::size_t joins = 0; joins < options.max_joins_per_change;) {
    const Element& keeper = state.elements.at(number);
    const Box near = Box::of(keeper.segment, candidate_margin(options.join));
    std::optional<fusion::MatchResult> best;
    std::int64_t best_number = 0;
    bool keeper_is_piece = false, other_is_piece = false;
    for (const auto other_number : state.elements.near(near)) {
      const Element& other = state.elements.at(other_number);
      if (other_number == number || declined.count(other_number) || !Box::of(other.segment).overlaps(near) ||
          (keeper.moments + other.moments).rms_offset_m() > join_straightness_allowance_m(keeper, other, options))
        continue;
      if (!faces_agree(keeper.facing_rad, other.facing_rad)) {
        // Seen from opposite sides: one surface only if it is thin (a partition, a wall drawn as one line), i.e.
        // the two lie within thin_surface_m of each other where they overlap; the faces of a thicker wall stay two.
        const auto gate = fusion::segment_gate(keeper.segment, other.segment, options.join);
        if (gate.passes && std::max(gate.offset_m[0], gate.offset_m[1]) <= options.thin_surface_m &&
            (!best || gate.cost < best->cost)) {
          best =
              fusion::MatchResult{0, fusion::mahalanobis_squared(keeper.segment.line, other.segment.line), gate.cost};
          best_number = other_number;
          keeper_is_piece = other_is_piece = false;
        }
        continue;
      }
      auto m = fusion::match_segment(keeper.segment, other.segment, options.join);
      bool keeper_piece = false, other_piece = false;
      const double band = options.max_straightness_rms_m, gap = options.join.max_gap_m;
      if (!m && ((other_piece = lies_within(other, keeper, band, gap)) ||
                 (keeper_piece = lies_within(keeper, other, band, gap)))) {
        constexpr double kAfterGated = 1e6;
        // Of the pieces, the longest first; of the walls the grown element is a piece of, the longest.
        m = fusion::MatchResult{0, fusion::mahalanobis_squared(keeper.segment.line, other.segment.line),
                                kAfterGated - other.segment.length_m()};
      }
      if (m && (!best || m->cost < best->cost)) {
        best = m;
        best_number = other_number;
        keeper_is_piece = keeper_piece;
        other_is_piece = other_piece;
      }
    }
    if (!best) return;
    if (keeper_is_piece) {
      if (join_into(result, best_number, number, *best, true, observation, observation_seq, options, decide)) return;
    } else if (join_into(result, number, best_number, *best, other_is_piece, observation, observation_seq, options,
                         decide)) {
      ++joins;
      continue;
    }
    declined.insert(best_number);
  }
}

// How far a rigid object may have been carried and still be found by its shape (its centroid's move) [m], and
// the bounds that keep the search cheap: objects per observation, segments per object.
constexpr double kShapeSearchM = 1.0;
constexpr std::size_t kShapeObjects = 4;
constexpr std::size_t kShapeSegments = 24;

// Rigid objects found again by their shape in one observation: per segment the object and edge it lies on, and
// the pose each object was found at.
struct FoundByShape {
  std::vector<std::optional<CandidateRef>> ref;
  std::map<std::size_t, fusion::Pose2D> pose;
};

double distance_to_segment(const Eigen::Vector2d& p, const fusion::LineSegment& s) {
  const Eigen::Vector2d a = s.p0(), d = s.p1() - a;
  const double len2 = d.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

// A rigid object carried beyond its gate leaves its views unmatched (or matched to it at the old pose, the wrong
// way). Several such views of one observation near a rigid object that its edges explain after one rigid
// transform (fusion::find_by_shape: lengths and extents included, so the walls beside it do not count) are taken
// as views of it. Only objects within kShapeSearchM of the observation, only when at least one of the views is
// unmatched, and only views that match nothing else.
FoundByShape find_moved_objects(const WorldState& state, const Observation& observation, const WorldOptions& options) {
  FoundByShape found;
  const std::size_t n = observation.segments.size();
  found.ref.resize(n);
  if (n < 2 || state.objects.empty()) return found;
  Box box{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::lowest(),
          std::numeric_limits<double>::lowest()};
  for (const auto& s : observation.segments) {
    const Box b = Box::of(s.segment);
    box = {std::min(box.x0, b.x0), std::min(box.y0, b.y0), std::max(box.x1, b.x1), std::max(box.y1, b.y1)};
  }
  box = {box.x0 - kShapeSearchM, box.y0 - kShapeSearchM, box.x1 + kShapeSearchM, box.y1 + kShapeSearchM};
  // Nearest objects first: their centroid's distance to the closest segment.
  std::vector<std::pair<double, std::size_t>> objects;
  for (const auto& [i, k] : state.objects.edges_near(box)) {
    if ((!objects.empty() && objects.back().second == i) || !is_rigid(state.objects[i])) continue;
    const auto& body = state.objects[i].body;
    const Eigen::Vector2d centre = body.pose().transform_point(body.local_centroid());
    double nearest = std::numeric_limits<double>::max();
    for (const auto& s : observation.segments) nearest = std::min(nearest, distance_to_segment(centre, s.segment));
    objects.emplace_back(nearest, i);
  }
  std::sort(objects.begin(), objects.end());
  if (objects.size() > kShapeObjects) objects.resize(kShapeObjects);

  // What each segment matches in the map as it is (asked only of segments near a searched object, once): nullopt
  // nothing, else the candidate's object index, kElement for an element.
  constexpr std::size_t kElement = std::numeric_limits<std::size_t>::max();
  std::vector<std::optional<std::optional<std::size_t>>> matched(n);
  std::vector<std::int64_t> matched_element(n, 0);  // the element number when matched[i] is kElement
  for (const auto& [nearest, index] : objects) {
    const auto& body = state.objects[index].body;
    const Eigen::Vector2d centre = body.pose().transform_point(body.local_centroid());
    double radius = 0.0;
    for (const auto& e : body.edges()) {
      radius = std::max(radius, (body.pose().transform_point(e.p0) - centre).norm());
      radius = std::max(radius, (body.pose().transform_point(e.p1) - centre).norm());
    }
    std::vector<std::size_t> group;
    bool any_unmatched = false;
    for (std::size_t i = 0; i < n; ++i) {
      const auto& seen = observation.segments[i].segment;
      if (found.ref[i] || distance_to_segment(centre, seen) > kShapeSearchM + radius) continue;
      if (!matched[i]) {
        const Candidates candidates = collect_candidates(state, seen, observation.segments[i].facing_rad, options);
        const auto m = fusion::best_match(candidates.segments, seen, options.match);
        matched[i] = !m ? std::optional<std::size_t>{} : candidates.refs[m->index].object.value_or(kElement);
        if (m && !candidates.refs[m->index].object) matched_element[i] = candidates.refs[m->index].element;
      }
      const auto& what = *matched[i];
      // A view matched to an element that lies on the object's reach may be a view of the carried object whose
      // earlier views, seen one side at a time, became elements before two sides showed in one scan.
      bool element_near = false;
      if (what && *what == kElement)
        if (const Element* e = state.elements.find(matched_element[i]))
          element_near = distance_to_segment(centre, e->segment) <= radius + kShapeSearchM;
      if (what && *what != index && !element_near) continue;  // a view of something else
      any_unmatched |= !what || element_near;
      group.push_back(i);
    }
    if (group.size() < 2 || !any_unmatched) continue;
    std::stable_sort(group.begin(), group.end(), [&](std::size_t a, std::size_t b) {
      return observation.segments[a].segment.length_m() > observation.segments[b].segment.length_m();
    });
    if (group.size() > kShapeSegments) group.resize(kShapeSegments);
    std::vector<fusion::LineSegment> segments;
    for (const auto i : group) segments.push_back(observation.segments[i].segment);
    fusion::ShapeFitOptions fit_options;
    fit_options.max_shift_m = kShapeSearchM;
    const auto fit = fusion::find_by_shape(body, segments, fit_options);
    if (!fit) continue;
    bool explains_unmatched = false;
    for (std::size_t g = 0; g < group.size(); ++g)
      explains_unmatched |= fit->edge_of[g] && (!*matched[group[g]] || **matched[group[g]] == kElement);
    if (!explains_unmatched) continue;
    for (std::size_t g = 0; g < group.size(); ++g)
      if (fit->edge_of[g]) found.ref[group[g]] = CandidateRef{index, *fit->edge_of[g], 0};
    found.pose[index] = fit->pose;
  }
  return found;
}

// A new element from an observed segment (the add action); its number.
std::int64_t add_element(UpdateResult& result, const ObservedSegment& seen, const Observation& observation) {
  WorldState& state = result.state;
  Element element;
  element.number = state.next_element_number++;
  element.segment = seen.segment;
  element.moments = fusion::SegmentMoments::of(seen.segment);
  element.facing_rad = seen.facing_rad;
  element.origin = observation.origin;
  element.observer = observation.observer;
  element.created_version = state.version;
  element.updated_version = state.version;
  element.updated_at_unix_s = observation.received_at_unix_s;
  const std::int64_t number = element.number;
  result.changed_elements.insert(number);
  state.elements.put(std::move(element));
  return number;
}

// The lines of one observation the rules sent to rigid_adjust one object: applied together, once.
struct PendingRigid {
  std::vector<fusion::EdgeObservation> lines;
  std::vector<std::size_t> records;   // into result.decisions, one per line
  std::vector<std::size_t> segments;  // into observation.segments, one per line
  bool by_shape = false;              // some of them were found by the object's shape
};

// After a carried object was found by its shape and moved there: the elements its earlier views became (seen one
// side at a time, before two sides showed in one scan) lie on its edges now. They are views of the object, not walls:
// each goes with a prune decision (rule object_found). An element lies on an edge when both its ends are within
// 5 cm of the edge's line, its direction within 5° and its extent within the edge's plus 10 cm.
void absorb_elements(UpdateResult& result, std::size_t index, const Observation& observation,
                     std::int64_t observation_seq) {
  constexpr double kOffsetM = 0.05, kAngleRad = 0.0873, kBeyondM = 0.10;
  WorldState& state = result.state;
  const ObjectState& object = state.objects[index];
  std::vector<fusion::LineSegment> edges;
  Box box{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::lowest(),
          std::numeric_limits<double>::lowest()};
  for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
    edges.push_back(object.body.world_edge(k, Eigen::Matrix2d::Zero()));
    const Box b = Box::of(edges.back(), kBeyondM);
    box = {std::min(box.x0, b.x0), std::min(box.y0, b.y0), std::max(box.x1, b.x1), std::max(box.y1, b.y1)};
  }
  for (const auto number : state.elements.near(box)) {
    const Element* element = state.elements.find(number);
    if (!element) continue;
    const auto& seg = element->segment;
    const bool on_an_edge = std::any_of(edges.begin(), edges.end(), [&](const fusion::LineSegment& edge) {
      const double angle = std::abs(std::remainder(seg.line.phi_rad - edge.line.phi_rad, std::numbers::pi));
      if (angle > kAngleRad) return false;
      for (const Eigen::Vector2d& p : {seg.p0(), seg.p1()}) {
        if (std::abs(edge.line.signed_distance(p)) > kOffsetM) return false;
        const double t = edge.line.coordinate_along(p);
        if (t < edge.t0_m - kBeyondM || t > edge.t1_m + kBeyondM) return false;
      }
      return true;
    });
    if (!on_an_edge) continue;
    remove_element(result, number, "object_found",
                   element->id() + " lies on an edge of " + object.plan->id +
                       ", found again by its shape where it was carried: a view of it, not a wall",
                   observation.observer, observation_seq)
        .object = object.plan->id;
  }
}

// One joint update of object `index` from every line the rules sent to it (one edge alone fixes only its normal and
// the turn). When the object was found by its shape, its covariance first widens to cover the move (it was
// carried) and the iteration starts at the pose found. If the update fails, each line becomes the fallback add.
void apply_rigid(UpdateResult& result, std::size_t index, const PendingRigid& pending, const FoundByShape& found,
                 const Observation& observation, std::int64_t observation_seq, const WorldOptions& options,
                 const Decide& decide) {
  WorldState& state = result.state;
  ObjectState object = state.objects[index];
  fusion::RigidObject body = object.body;
  fusion::RigidUpdateOptions how;
  if (const auto at = found.pose.find(index); pending.by_shape && at != found.pose.end()) {
    body = body.with_move_allowed(at->second);
    how.start = at->second;
  }
  try {
    const auto before = pose_numbers(object.body);
    object.body = body.updated(pending.lines, how);
    const auto after = pose_numbers(object.body);
    for (const auto r : pending.records) {
      result.decisions[r].before = before;
      result.decisions[r].after = after;
    }
    object.adjustments += static_cast<std::int64_t>(pending.lines.size());
    object.updated_version = state.version;
    state.objects.put(index, std::move(object));
    result.changed_objects.insert(index);
    if (pending.by_shape) absorb_elements(result, index, observation, observation_seq);
  } catch (const std::invalid_argument& e) {
    for (std::size_t j = 0; j < pending.records.size(); ++j) {
      DecisionRecord& record = result.decisions[pending.records[j]];
      make_fallback(record, rules::wire_name(rules::Action::rigid_adjust),
                    std::string("rigid update failed: ") + e.what());
      record.object.reset();
      const auto number = add_element(result, observation.segments[pending.segments[j]], observation);
      record.element = element_id(number);
      join_neighbours(result, number, observation, observation_seq, options, decide);
    }
  }
}

// Whether element `e` was made from grid lines alone, or from scans or by a client.
bool made_by_grid(const Element& e) { return e.origin == "grid"; }

// The element made from scans or by a client that the grid line lies on (GridLineMatchOptions), the closest (the
// larger of the grid line's end offsets); nullopt when there is none.
std::optional<std::int64_t> grid_line_on_element(const WorldState& state, const fusion::LineSegment& seen,
                                                 const GridLineMatchOptions& options) {
  std::optional<std::int64_t> best;
  double best_offset = std::numeric_limits<double>::infinity();
  for (const auto number : state.elements.near(Box::of(seen, options.on_element_offset_m))) {
    const Element& element = state.elements.at(number);
    if (made_by_grid(element)) continue;
    const fusion::LineSegment& e = element.segment;
    if (std::abs(std::remainder(seen.line.phi_rad - e.line.phi_rad, std::numbers::pi)) > options.on_element_angle_rad)
      continue;
    const double ta = e.line.coordinate_along(seen.p0()), tb = e.line.coordinate_along(seen.p1());
    if (std::min(std::max(ta, tb), e.t1_m) < std::max(std::min(ta, tb), e.t0_m)) continue;  // end to end
    const double offset =
        std::max(std::abs(e.line.signed_distance(seen.p0())), std::abs(e.line.signed_distance(seen.p1())));
    if (offset > options.on_element_offset_m || offset >= best_offset) continue;
    best = number;
    best_offset = offset;
  }
  return best;
}

// The stretch [t0, t1] along `line` [m] over which the segment lies within `offset_m` of it; nullopt when nowhere.
std::optional<std::pair<double, double>> stretch_within(const fusion::LineFeature& line,
                                                        const fusion::LineSegment& segment, double offset_m) {
  double ta = line.coordinate_along(segment.p0()), tb = line.coordinate_along(segment.p1());
  double oa = line.signed_distance(segment.p0()), ob = line.signed_distance(segment.p1());
  if (ta > tb) {
    std::swap(ta, tb);
    std::swap(oa, ob);
  }
  // The offset runs linearly from oa at ta to ob at tb.
  double lo = ta, hi = tb;
  if (std::abs(ob - oa) > 1e-12) {
    const double slope = (ob - oa) / (tb - ta);
    const double u = (offset_m - oa) / slope, v = (-offset_m - oa) / slope;
    lo = std::max(lo, ta + std::min(u, v));
    hi = std::min(hi, ta + std::max(u, v));
  } else if (std::abs(oa) > offset_m) {
    return std::nullopt;
  }
  if (hi < lo) return std::nullopt;
  return std::pair{lo, hi};
}

// After a grid extraction: an element cannot run on behind a surface the grid saw. Each element whose end runs past
// the line of one of `surfaces` (the elements the extraction's lines confirmed, merged into or became) near that
// surface's extent, crossing it at a real angle, is cut back to it when the part past it is short and the rest of
// the element lies on the other side (GridLineMatchOptions). Why: an element's extent is the union of its views,
// and near a corner the extreme views of a few hundred reach 5–10 cm behind the other wall; the grid trim does not
// see that, as the other wall's occupied band backs it. Each cut is a "trim" decision (rule grid_crossing_trimmed)
// with the old and new endpoints; the line, its covariance and its moments stay. Client elements are not cut.
void cut_at_grid_surfaces(UpdateResult& result, const std::set<std::int64_t>& surfaces, const Observation& observation,
                          std::int64_t observation_seq, const GridLineMatchOptions& options) {
  WorldState& state = result.state;
  for (const auto surface_number : surfaces) {
    const Element* surface = state.elements.find(surface_number);
    if (!surface) continue;
    const fusion::LineSegment wall = surface->segment;
    const std::string wall_id = surface->id();
    const Eigen::Vector2d nw = wall.line.normal();
    for (const auto number :
         state.elements.near(Box::of(wall, options.max_corner_cut_m + options.on_element_offset_m))) {
      if (number == surface_number) continue;
      const Element& element = state.elements.at(number);
      if (element.origin == "client") continue;
      const fusion::LineSegment& s = element.segment;
      if (std::abs(std::remainder(s.line.phi_rad - wall.line.phi_rad, std::numbers::pi)) <
          options.min_crossing_angle_rad)
        continue;
      // Where the lines cross: n_s·X = ρ_s and n_w·X = ρ_w.
      const Eigen::Vector2d ns = s.line.normal();
      const double det = ns.x() * nw.y() - ns.y() * nw.x();  // sin of the angle between them: not small here
      const Eigen::Vector2d crossing((s.line.rho_m * nw.y() - ns.y() * wall.line.rho_m) / det,
                                     (ns.x() * wall.line.rho_m - s.line.rho_m * nw.x()) / det);
      const double along_wall = wall.line.coordinate_along(crossing);
      if (along_wall < wall.t0_m - options.on_element_offset_m || along_wall > wall.t1_m + options.on_element_offset_m)
        continue;
      const double t = s.line.coordinate_along(crossing);
      const double past_hi = s.t1_m - t, past_lo = t - s.t0_m;
      fusion::LineSegment cut = s;
      if (past_hi >= options.min_corner_cut_m && past_hi <= options.max_corner_cut_m &&
          past_lo > options.max_corner_cut_m) {
        cut.t1_m = t;
      } else if (past_lo >= options.min_corner_cut_m && past_lo <= options.max_corner_cut_m &&
                 past_hi > options.max_corner_cut_m) {
        cut.t0_m = t;
      } else {
        continue;
      }
      Element trimmed = element;
      trimmed.segment = cut;
      trimmed.updated_version = state.version;
      trimmed.updated_at_unix_s = observation.received_at_unix_s;

      DecisionRecord record;
      record.seq = ++state.last_decision_seq;
      record.observation_seq = observation_seq;
      record.index = -1;  // not about a segment of the request
      record.action = rules::Action::trim;
      record.rule = "grid_crossing_trimmed";
      char text[256];
      std::snprintf(text, sizeof text,
                    "element %s ran %.3f m past element %s, a surface the grid line extractor saw: cut from %.3f m "
                    "to %.3f m",
                    element.id().c_str(), s.length_m() - cut.length_m(), wall_id.c_str(), s.length_m(), cut.length_m());
      record.explanation = text;
      record.element = element.id();
      record.matched_element = wall_id;
      record.observer = observation.observer;
      record.origin = observation.origin;
      record.sensor = observation.sensor;
      record_observed(record, cut);
      const Eigen::Vector2d a = s.p0(), b = s.p1();
      record.before = {a.x(), a.y(), b.x(), b.y()};
      record.after = {record.p0.x(), record.p0.y(), record.p1.x(), record.p1.y()};
      result.decisions.push_back(std::move(record));
      result.changed_elements.insert(number);
      state.elements.put(std::move(trimmed));
    }
  }
}

std::string pose_text(const fusion::Pose2D& pose) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.3f, %.3f, %.4f)", pose.x_m, pose.y_m, pose.theta_rad);
  return text;
}

}  // namespace

double facing_toward(const fusion::LineSegment& segment, const Eigen::Vector2d& viewpoint) {
  const double phi = segment.line.phi_rad;
  return segment.line.signed_distance(viewpoint) >= 0 ? phi
                                                      : std::remainder(phi + std::numbers::pi, 2 * std::numbers::pi);
}

bool faces_agree(const std::optional<double>& a, const std::optional<double>& b) {
  return !a || !b || std::cos(*a - *b) > 0;
}

UpdateResult apply_observation(const WorldState& current, const Observation& observation, std::int64_t observation_seq,
                               const WorldOptions& options, const Decide& decide) {
  UpdateResult result{current, {}, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.last_observation_seq = observation_seq;

  const FoundByShape found = find_moved_objects(current, observation, options);
  std::map<std::size_t, PendingRigid> pending;  // by object index
  const bool grid_line = observation.origin == "grid";
  std::set<std::int64_t> grid_surfaces;  // the elements a grid line confirmed, merged into or became

  for (std::size_t i = 0; i < observation.segments.size(); ++i) {
    const auto& seen = observation.segments[i].segment;
    // Matching runs against the map as changed by the earlier segments of the same request (rigid objects move
    // once, after the last segment).
    Candidates candidates = collect_candidates(state, seen, observation.segments[i].facing_rad, options);
    auto match = fusion::best_match(candidates.segments, seen, options.match);
    if (grid_line && !found.ref[i] && !(match && candidates.refs[match->index].object)) {
      // A grid line is known to a cell across (and a short one fitted near a corner may lean by a degree): on a
      // wall the scans mapped it can fall outside that element's segment gate, whose σ are the scans' own.
      if (const auto on = grid_line_on_element(state, seen, options.grid_lines)) {
        std::size_t k = 0;
        while (k < candidates.refs.size() && (candidates.refs[k].object || candidates.refs[k].element != *on)) ++k;
        if (k == candidates.refs.size()) {
          candidates.segments.push_back(state.elements.at(*on).segment);
          candidates.refs.push_back({std::nullopt, 0, *on});
        }
        match = fusion::MatchResult{k, fusion::mahalanobis_squared(candidates.segments[k].line, seen.line), 0.0};
      }
    }
    if (found.ref[i]) {
      // A view of a carried object: matched to its edge where its shape was found.
      const CandidateRef& f = *found.ref[i];
      const ObjectState& object = state.objects[*f.object];
      const fusion::RigidObject there(found.pose.at(*f.object), object.body.pose_cov(), object.body.edges());
      candidates.segments.push_back(there.world_edge(f.edge, apriori_edge_noise(object, f.edge, options)));
      candidates.refs.push_back(f);
      match = fusion::MatchResult{candidates.segments.size() - 1,
                                  fusion::mahalanobis_squared(candidates.segments.back().line, seen.line), 0.0};
    }
    const auto query = make_query(state, observation, seen, match, candidates);
    const rules::Decision decision = decide(query);

    DecisionRecord record;
    record.seq = ++state.last_decision_seq;
    record.observation_seq = observation_seq;
    record.index = static_cast<std::int64_t>(i);
    // The rules' atom becomes an Action here, once; an atom the server does not know is the fallback add.
    const auto action = rules::parse_action(decision.action);
    record.action = action.value_or(rules::Action::add);
    record.rule = decision.rule;
    record.explanation = decision.explanation;
    if (found.ref[i])
      record.explanation +=
          " (matched by the object's shape, found at " + pose_text(found.pose.at(*found.ref[i]->object)) + ")";
    record.fallback = decision.fallback;
    record.element = query.element_id;
    record.object = query.object_id;
    record.matched_element = query.element_id;
    record.matched_object = query.object_id;
    if (match) record.mahalanobis_sq = match->mahalanobis_sq;
    record.observer = observation.observer;
    record.origin = observation.origin;
    record.sensor = observation.sensor;
    record_observed(record, seen);

    const CandidateRef* ref = match ? &candidates.refs[match->index] : nullptr;
    std::optional<std::int64_t> grown;  // the element a merge or add changed, whose neighbours are checked next
    if (!action || *action == rules::Action::prune || *action == rules::Action::trim) {
      make_fallback(record, decision.action, "action '" + decision.action + "' is not known to the server");
    } else if (record.action == rules::Action::merge && !ref) {
      make_fallback(record, decision.action, "merge needs a match");
    } else if (record.action == rules::Action::rigid_adjust && !(ref && ref->object)) {
      make_fallback(record, decision.action, "rigid_adjust needs a matched CAD object");
    }

    // A grid line merged into an element that scans or a client made gives it its support and its extent, not its
    // line: the element's line, covariance and moments stay what its own views say (the grid knows the surface to
    // a cell, those views to a centimetre or two). The grid line's ends lie on the surface's ends to half a cell,
    // and an end past a wall the grid saw is cut back to it after the last line (cut_at_grid_surfaces).
    const bool grid_on_measured = grid_line && ref && !ref->object && !made_by_grid(state.elements.at(ref->element));
    if (grid_line && ref && !ref->object && record.action == rules::Action::confirm) grid_surfaces.insert(ref->element);

    if (record.action == rules::Action::confirm) {
      if (ref && ref->object) {
        ObjectState object = state.objects[*ref->object];
        ++object.confirmations;
        object.updated_version = state.version;
        state.objects.put(*ref->object, std::move(object));
        result.changed_objects.insert(*ref->object);
      } else if (ref) {
        Element element = state.elements.at(ref->element);
        ++element.support;
        element.updated_version = state.version;
        element.updated_at_unix_s = observation.received_at_unix_s;
        state.elements.put(std::move(element));
        result.changed_elements.insert(ref->element);
      }
    } else if (record.action == rules::Action::merge && !ref->object) {
      Element element = state.elements.at(ref->element);
      record.before = line_numbers(element.segment.line);
      if (grid_on_measured) {
        if (const auto stretch = stretch_within(element.segment.line, seen, options.grid_lines.extend_offset_m)) {
          element.segment.t0_m = std::min(element.segment.t0_m, stretch->first);
          element.segment.t1_m = std::max(element.segment.t1_m, stretch->second);
        }
        record.explanation += " (a grid line on an element from scans or a client: its extent taken in, not its line)";
      } else {
        element.moments += fusion::SegmentMoments::of(seen);
        element.segment = fused_and_refit(fusion::fuse(element.segment, seen, options.fusion), element.moments);
        if (!element.facing_rad) element.facing_rad = observation.segments[i].facing_rad;
      }
      record.after = line_numbers(element.segment.line);
      ++element.support;
      element.updated_version = state.version;
      element.updated_at_unix_s = observation.received_at_unix_s;
      state.elements.put(std::move(element));
      result.changed_elements.insert(ref->element);
      grown = ref->element;
    } else if (record.action == rules::Action::merge) {
      // Merged into a CAD edge (e.g. a door that moves): the drawing stays as drawn; the observed state
      // becomes an element that starts from the fusion of the drawn edge and the observation.
      const auto& object = state.objects[*ref->object];
      const auto drawn = apriori_edge(object, ref->edge, options);
      record.before = line_numbers(drawn.line);
      Element element;
      element.number = state.next_element_number++;
      element.segment = fusion::fuse(drawn, seen, options.fusion);
      element.moments = fusion::SegmentMoments::of(seen);
      element.facing_rad = observation.segments[i].facing_rad;
      element.support = 2;
      element.origin = observation.origin;
      element.observer = observation.observer;
      element.created_version = element.updated_version = state.version;
      element.updated_at_unix_s = observation.received_at_unix_s;
      record.after = line_numbers(element.segment.line);
      record.element = element.id();
      result.changed_elements.insert(element.number);
      grown = element.number;
      state.elements.put(std::move(element));
    } else if (record.action == rules::Action::rigid_adjust) {
      // Deferred: every line of this observation on the object goes into one joint update (apply_rigid).
      PendingRigid& p = pending[*ref->object];
      p.lines.push_back({ref->edge, seen.line, apriori_edge_noise(state.objects[*ref->object], ref->edge, options)});
      p.records.push_back(result.decisions.size());
      p.segments.push_back(i);
      p.by_shape |= found.ref[i].has_value();
    }
    if (record.action == rules::Action::add) {
      const auto number = add_element(result, observation.segments[i], observation);
      record.element = element_id(number);
      record.object.reset();
      grown = number;  // a view that missed the scan-line gate may still lie on an element
    }
    result.decisions.push_back(std::move(record));
    if (grown) join_neighbours(result, *grown, observation, observation_seq, options, decide);
    // The element a grid line merged into or became, unless a join took it into another one: a surface the grid saw.
    if (grid_line && grown && state.elements.contains(*grown)) grid_surfaces.insert(*grown);
  }
  for (const auto& [index, p] : pending)
    apply_rigid(result, index, p, found, observation, observation_seq, options, decide);
  if (grid_line) cut_at_grid_surfaces(result, grid_surfaces, observation, observation_seq, options.grid_lines);
  return result;
}

void apply_prune(UpdateResult& result, const std::vector<rules::PruneOrder>& orders, std::int64_t observation_seq,
                 const std::string& observer) {
  WorldState& state = result.state;
  for (const auto& order : orders) {
    const auto number = WorldState::element_number(order.element_id);
    if (!number) continue;
    if (!state.elements.contains(*number)) continue;
    remove_element(result, *number, order.rule, order.explanation, observer, observation_seq).element =
        order.element_id;
  }
}

rules::DecisionQuery DecisionRecord::query() const {
  rules::DecisionQuery q;
  q.observer = observer;
  q.rho_m = rho_m;
  q.phi_rad = phi_rad;
  q.length_m = (p1 - p0).norm();
  q.origin = origin;
  q.sensor = sensor;
  if (matched_element) {
    q.element_id = matched_element;
    q.object_id = matched_object;
    q.mahalanobis_sq = mahalanobis_sq.value_or(0.0);
  }
  return q;
}

UpdateResult apply_floor_plan(const WorldState& current, const apriori::FloorPlan& plan, const WorldOptions& options) {
  UpdateResult result{current, {}, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.plan_name = plan.name;
  state.objects = ObjectTable(make_objects(plan, options, state.version, current.placement));
  for (std::size_t i = 0; i < state.objects.size(); ++i) result.changed_objects.insert(i);
  return result;
}

std::vector<double> placement_numbers(const fusion::Similarity2D& placement, const Eigen::Matrix4d& cov) {
  std::vector<double> numbers{placement.x_m, placement.y_m, placement.theta_rad, placement.scale};
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) numbers.push_back(cov(r, c));
  return numbers;
}

UpdateResult apply_placement(const WorldState& current, const PlacementChange& change, std::int64_t observation_seq) {
  UpdateResult result{current, {}, {}, {}, {}};
  WorldState& state = result.state;
  state.version = current.version + 1;
  state.last_observation_seq = observation_seq;
  state.placement = change.placement;
  state.placement_cov = change.cov;
  // A new table: a change of scale changes the edges without moving the poses, which ObjectTable::put would not
  // re-index.
  std::vector<ObjectState> objects;
  objects.reserve(current.objects.size());
  for (std::size_t i = 0; i < current.objects.size(); ++i) {
    objects.push_back(replaced(current.objects[i], current.placement, change.placement));
    objects.back().updated_version = state.version;
    result.changed_objects.insert(i);
  }
  state.objects = ObjectTable(std::move(objects));
  DecisionRecord d;
  d.seq = ++state.last_decision_seq;
  d.observation_seq = observation_seq;
  d.action = rules::Action::place;
  d.rule = change.rule;
  d.explanation = change.explanation;
  d.observer = change.observer;
  d.origin = "client";
  d.sensor = "none";
  d.before = placement_numbers(current.placement, current.placement_cov);
  d.after = placement_numbers(change.placement, change.cov);
  result.decisions.push_back(std::move(d));
  return result;
}

}  // namespace wm::world
