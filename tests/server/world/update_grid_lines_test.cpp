#include <gtest/gtest.h>

#include <cstdint>
#include <set>
#include <string>

#include "server/world/update.h"
#include "tests/server/world/update_test_helpers.h"

namespace wm::world {
namespace {

using namespace update_test_helpers;

// --- Lines of the grid line extractor (origin "grid") against elements that scans made. ---

// Segments as one origin sends them; a grid line's covariance as the extractor's fit gives it (σ 3 mm across the
// middle, 0.05° in direction: many cells), so a line a few centimetres off fails the segment gate.
Observation from(const std::string& origin, std::initializer_list<std::pair<Eigen::Vector2d, Eigen::Vector2d>> segments,
                 const WorldOptions& o) {
  Observation obs = observe(segments, o);
  obs.origin = origin;
  obs.observer = origin == "grid" ? "grid-extractor" : "robot";
  obs.sensor = origin == "grid" ? "grid" : "laser";
  if (origin == "grid")
    for (auto& s : obs.segments) s.segment.line.cov = midpoint_line_cov(s.segment, 0.003, 0.0009);
  return obs;
}

// Merge on a match, add otherwise; maintenance joins refused.
struct MergingRules {
  std::vector<rules::DecisionQuery> asked;
  rules::Decision operator()(const rules::DecisionQuery& q) {
    asked.push_back(q);
    if (q.origin == "element") return {"add", "test_rule", "kept apart", false};
    if (q.element_id) return {"merge", "unknown_element_merged", "an element", false};
    return {"add", "unmatched_added", "nothing matched", false};
  }
};

// A grid line 4 cm off a scan-built wall (the band's centre behind it, or a cell off when on its surface) is the
// same wall: merged into the element, it lends it its extent and changes nothing else, not its line, covariance or
// moments.
TEST(GridLineTest, AGridLineOnAnElementFromScansLendsItItsExtentNotItsLine) {
  WorldOptions options;
  FixedRules add{"add", {}};
  const auto scanned =
      apply_observation(WorldState{}, from("scan", {{{0, 0}, {4, 0}}}, options), 1, options, std::ref(add)).state;
  const Element before = scanned.elements.at(1);
  MergingRules rules;
  const auto result =
      apply_observation(scanned, from("grid", {{{-0.1, -0.04}, {4.3, -0.04}}}, options), 2, options, std::ref(rules));
  ASSERT_EQ(rules.asked.size(), 1u);
  EXPECT_EQ(rules.asked[0].element_id, "e1") << "matched although outside the segment gate";
  EXPECT_EQ(rules.asked[0].origin, "grid");
  ASSERT_EQ(result.decisions.size(), 1u);
  const DecisionRecord& d = result.decisions[0];
  EXPECT_EQ(d.action, rules::Action::merge);
  EXPECT_EQ(d.rule, "unknown_element_merged");
  EXPECT_NE(d.explanation.find("its extent taken in, not its line"), std::string::npos) << d.explanation;
  EXPECT_EQ(d.before, d.after);
  ASSERT_EQ(result.state.elements.size(), 1u);
  const Element& after = result.state.elements.at(1);
  EXPECT_EQ(after.support, 2);
  EXPECT_EQ(after.segment.line.rho_m, before.segment.line.rho_m);
  EXPECT_EQ(after.segment.line.phi_rad, before.segment.line.phi_rad);
  EXPECT_EQ(after.segment.line.cov, before.segment.line.cov);
  EXPECT_EQ(after.moments.weight, before.moments.weight);
  EXPECT_NEAR(after.segment.p0().x(), -0.1, 1e-9);
  EXPECT_NEAR(after.segment.p1().x(), 4.3, 1e-9);
  EXPECT_NEAR(after.segment.p1().y(), 0.0, 1e-9);

  // Mostly beyond the element, overlapping it by 0.2 m: the same wall, seen further by the grid.
  MergingRules on;
  const auto further =
      apply_observation(scanned, from("grid", {{{3.8, 0.03}, {7, 0.03}}}, options), 2, options, std::ref(on));
  EXPECT_EQ(on.asked[0].element_id, "e1");
  ASSERT_EQ(further.state.elements.size(), 1u);
  EXPECT_NEAR(further.state.elements.at(1).segment.p1().x(), 7.0, 1e-9);
  EXPECT_EQ(further.state.elements.at(1).segment.line.rho_m, before.segment.line.rho_m);

  // 12 cm off, or turned by 2.3° (8 cm off at its ends): another wall as far as the grid can tell.
  MergingRules far;
  const auto beside =
      apply_observation(scanned, from("grid", {{{0, -0.12}, {4, -0.12}}}, options), 2, options, std::ref(far));
  EXPECT_FALSE(far.asked[0].element_id.has_value());
  EXPECT_EQ(beside.state.elements.size(), 2u);
  const auto turned =
      apply_observation(scanned, from("grid", {{{0, -0.08}, {4, 0.08}}}, options), 2, options, std::ref(far));
  EXPECT_FALSE(far.asked[1].element_id.has_value());
  EXPECT_EQ(turned.state.elements.size(), 2u);
}

// Where no element from scans lies, grid lines are added, and a grid line on an element the grid made is fused into
// it as before.
TEST(GridLineTest, GridLinesAwayFromElementsFromScansAreAddedAndFused) {
  WorldOptions options;
  FixedRules add{"add", {}};
  const auto scanned =
      apply_observation(WorldState{}, from("scan", {{{0, 0}, {4, 0}}}, options), 1, options, std::ref(add)).state;
  MergingRules rules;
  const auto added =
      apply_observation(scanned, from("grid", {{{0, 3}, {4, 3}}}, options), 2, options, std::ref(rules)).state;
  ASSERT_EQ(added.elements.size(), 2u);
  EXPECT_EQ(added.elements.at(2).origin, "grid");
  const auto fused =
      apply_observation(added, from("grid", {{{0, 3.002}, {4.5, 3.002}}}, options), 3, options, std::ref(rules));
  EXPECT_EQ(rules.asked.back().element_id, "e2");
  ASSERT_EQ(fused.decisions.size(), 1u);
  EXPECT_EQ(fused.decisions[0].action, rules::Action::merge);
  EXPECT_EQ(fused.state.elements.at(2).support, 2);
  EXPECT_NEAR(fused.state.elements.at(2).segment.length_m(), 4.5, 1e-3) << "a grid element takes the grid's extent";
}

// Elements whose ends ran a few centimetres past a corner or into a partition's wall are cut back to the surface the
// grid saw there (an element its lines confirmed); an element that passes by, one past by more than three cells, and
// one a client posted are left as they are.
TEST(GridLineTest, AnElementThatRunsPastASurfaceTheGridSawIsCutBackToIt) {
  WorldOptions options;
  FixedRules add{"add", {}};
  // Walls A (y = 0, 8 cm past the corner at x = 4) and B (x = 4, 6 cm below y = 0), a partition P (x = 2, 7 cm
  // below A's line), a wall Q (x = 1) reaching 30 cm below A's line, and a client's wall K (y = 3, 10 cm past B).
  auto state =
      apply_observation(
          WorldState{},
          from("scan", {{{0, 0}, {4.08, 0}}, {{4, -0.06}, {4, 3}}, {{2, -0.07}, {2, 2}}, {{1, -0.3}, {1, 2}}}, options),
          1, options, std::ref(add))
          .state;
  state = apply_observation(state, from("client", {{{0, 3}, {4.1, 3}}}, options), 2, options, std::ref(add)).state;
  ASSERT_EQ(state.elements.size(), 5u);
  MergingRules rules;
  const auto result =
      apply_observation(state, from("grid", {{{0.3, 0.025}, {3.95, 0.025}}, {{3.975, 0.2}, {3.975, 2.9}}}, options), 3,
                        options, std::ref(rules));
  const auto& e = result.state.elements;
  EXPECT_NEAR(e.at(1).segment.p1().x(), 4.0, 1e-9) << "A ends at B";
  EXPECT_NEAR(e.at(1).segment.p0().x(), 0.0, 1e-9);
  EXPECT_NEAR(std::min(e.at(2).segment.p0().y(), e.at(2).segment.p1().y()), 0.0, 1e-9) << "B ends at A";
  EXPECT_NEAR(std::min(e.at(3).segment.p0().y(), e.at(3).segment.p1().y()), 0.0, 1e-9) << "P ends at A";
  EXPECT_NEAR(std::min(e.at(4).segment.p0().y(), e.at(4).segment.p1().y()), -0.3, 1e-9) << "Q is left alone";
  EXPECT_NEAR(std::max(e.at(5).segment.p0().x(), e.at(5).segment.p1().x()), 4.1, 1e-9) << "K is a client's";
  for (std::int64_t n = 1; n <= 4; ++n) {
    EXPECT_EQ(e.at(n).segment.line.rho_m, state.elements.at(n).segment.line.rho_m);
    EXPECT_EQ(e.at(n).segment.line.phi_rad, state.elements.at(n).segment.line.phi_rad);
  }
  std::vector<const DecisionRecord*> trims;
  for (const auto& d : result.decisions)
    if (d.action == rules::Action::trim) trims.push_back(&d);
  ASSERT_EQ(trims.size(), 3u);
  for (const DecisionRecord* d : trims) {
    EXPECT_EQ(d->rule, "grid_crossing_trimmed");
    EXPECT_EQ(d->index, -1);
    EXPECT_EQ(d->origin, "grid");
    EXPECT_EQ(d->before.size(), 4u);
    EXPECT_EQ(d->after.size(), 4u);
  }
  EXPECT_EQ(result.changed_elements, (std::set<std::int64_t>{1, 2, 3}));
}

}  // namespace
}  // namespace wm::world
