// Joining elements that turn out to be views of one wall, and the straightness an element keeps.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <string_view>

#include "server/world/update_internal.h"

namespace wm::world::update_internal {
namespace {

// The same for joining two elements: each is already as straight as its views' spread let it be, so the join
// may spread WorldOptions::join_scatter_factor times as much as the less straight one, never less than the fixed
// allowance. (Their covariances would not do: the fusion floor gives every element 0.5° however good its poses.)
double join_straightness_allowance_m(const Element& a, const Element& b, const WorldOptions& options) {
  return std::max(options.max_straightness_rms_m,
                  options.join_scatter_factor * std::max(a.moments.rms_offset_m(), b.moments.rms_offset_m()));
}

// Whether `a` and `b` are two surfaces side by side (side_by_side), held to the straightness the shorter one's own
// views allow, or the join's allowance, whichever is larger.
bool steps_apart(const Element& a, const Element& b, const WorldOptions& options) {
  const Element& shorter = a.segment.length_m() < b.segment.length_m() ? a : b;
  const double allowance =
      std::max(join_straightness_allowance_m(a, b, options), straightness_allowance_m(shorter.segment, options));
  return side_by_side(a.moments, a.segment, b.moments, b.segment, allowance, !a.both_ways && !b.both_ways);
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
  joined.both_ways = keeper.both_ways || other.both_ways || !faces_agree(keeper.facing_rad, other.facing_rad);
  joined.facing_rad = joined.both_ways                ? std::nullopt
                      : keeper.facing_rad.has_value() ? keeper.facing_rad
                                                      : other.facing_rad;
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

}  // namespace

// A surface behind another, seen through the gap beside the nearer one's end at incidence θ, shows up to
// offset · tan θ of itself behind that end: 3 offsets is θ = 72°.
constexpr double kObliqueOverlapPerOffset = 3.0;

bool end_to_end(const fusion::LineSegment& a, const fusion::LineSegment& b) {
  const auto& longer = a.length_m() >= b.length_m() ? a : b;
  const auto& shorter = &longer == &a ? b : a;
  const double ta = longer.line.coordinate_along(shorter.p0()), tb = longer.line.coordinate_along(shorter.p1());
  const double overlap = std::min(std::max(ta, tb), longer.t1_m) - std::max(std::min(ta, tb), longer.t0_m);
  if (overlap < 0.5 * std::abs(tb - ta)) return true;
  // Seen obliquely past the longer one's end: the shorter one runs on beyond that end.
  const bool past_an_end = std::min(ta, tb) < longer.t0_m || std::max(ta, tb) > longer.t1_m;
  const double offset = std::abs(longer.line.signed_distance(0.5 * (shorter.p0() + shorter.p1())));
  return past_an_end && overlap < kObliqueOverlapPerOffset * offset;
}

bool side_by_side(const fusion::SegmentMoments& a, const fusion::LineSegment& a_segment,
                  const fusion::SegmentMoments& b, const fusion::LineSegment& b_segment, double allowance_m,
                  bool one_side) {
  if (one_side && !end_to_end(a_segment, b_segment)) return false;
  const bool a_shorter = a_segment.length_m() < b_segment.length_m();
  return (a_shorter ? a : b).rms_offset_from_m(a_shorter ? b_segment.line : a_segment.line) > allowance_m;
}

double straightness_allowance_m(const fusion::LineSegment& seen, const WorldOptions& options) {
  const double middle = 0.5 * (seen.t0_m + seen.t1_m), length = seen.length_m();
  const double spread_sq = std::max(0.0, fusion::offset_variance_at(seen.line, middle)) +
                           std::max(0.0, seen.line.cov(1, 1)) * length * length / 12.0;
  return std::max(options.max_straightness_rms_m, options.straightness_sigmas * std::sqrt(spread_sq));
}

fusion::LineSegment fused_and_refit(const fusion::LineSegment& fused, const fusion::SegmentMoments& moments) {
  return fusion::with_covariance_floor(moments.refit(fused).value_or(fused), {moments.rms_offset_m(), 0.0});
}

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
          (keeper.moments + other.moments).rms_offset_m() > join_straightness_allowance_m(keeper, other, options) ||
          steps_apart(keeper, other, options))
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

}  // namespace wm::world::update_internal
