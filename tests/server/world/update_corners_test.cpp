#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <functional>
#include <iterator>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/world/update.h"
#include "tests/server/world/update_test_helpers.h"

namespace wm::world {
namespace {

using namespace update_test_helpers;

constexpr double kDeg = std::numbers::pi / 180.0;

// A point `t` metres from (3, 0) along a facet turned `angle` below the x axis.
Eigen::Vector2d on_next_facet(double t, double angle) {
  return Eigen::Vector2d(3, 0) + t * Eigen::Vector2d(std::cos(angle), -std::sin(angle));
}

WorldState add_views(WorldState state, const std::vector<Observation>& views, const WorldOptions& options,
                     JoiningRules& rules, std::vector<DecisionRecord>* decisions = nullptr) {
  std::int64_t seq = 0;
  for (const auto& view : views) {
    auto result = apply_observation(state, view, ++seq, options, std::ref(rules));
    if (decisions) decisions->insert(decisions->end(), result.decisions.begin(), result.decisions.end());
    state = std::move(result.state);
  }
  return state;
}

std::vector<DecisionRecord> corner_cuts(const std::vector<DecisionRecord>& decisions) {
  std::vector<DecisionRecord> cuts;
  std::copy_if(decisions.begin(), decisions.end(), std::back_inserter(cuts),
               [](const DecisionRecord& d) { return d.rule == "corner_cut"; });
  return cuts;
}

// Two facets of a shallow bend (7°) at (3, 0), each seen with a piece of the other: the first runs 0.3 m past the
// corner (3.7 cm off the next facet's line at its end), the second starts 0.15 m before it. Whichever is seen
// first, each ends at the corner, with a trim decision that says where and by how much.
TEST(CornerCutTest, TwoFacetsOfAShallowBendEachEndAtTheCorner) {
  const double bend = 7 * kDeg;
  const Eigen::Vector2d viewpoint(2, 3);
  const auto first = view_from({0, 0}, {3.3, 0}, viewpoint, 0.01, 0.005);
  const auto second = view_from(on_next_facet(-0.15, bend), on_next_facet(2.0, bend), viewpoint, 0.01, 0.005);
  for (const bool first_first : {true, false}) {
    SCOPED_TRACE(first_first ? "the first facet seen first" : "the second facet seen first");
    WorldOptions options;
    JoiningRules rules;
    std::vector<DecisionRecord> decisions;
    const auto state = add_views(WorldState{}, first_first ? std::vector{first, second} : std::vector{second, first},
                                 options, rules, &decisions);
    ASSERT_EQ(state.elements.size(), 2u);
    const auto facet_on = [&](double angle) -> const fusion::LineSegment& {
      for (const auto& [number, e] : state.elements)
        if (std::abs(std::remainder(e.segment.line.phi_rad - (std::numbers::pi / 2 - angle), std::numbers::pi)) <
            0.5 * kDeg)
          return e.segment;
      throw std::runtime_error("no element along that facet");
    };
    const auto &a = facet_on(0), &b = facet_on(bend);
    EXPECT_NEAR(std::max(a.p0().x(), a.p1().x()), 3.0, 1e-6);
    EXPECT_NEAR(std::min(a.p0().x(), a.p1().x()), 0.0, 1e-6);
    EXPECT_NEAR(std::min(b.p0().x(), b.p1().x()), 3.0, 1e-6);
    EXPECT_NEAR(std::max(b.p0().x(), b.p1().x()), on_next_facet(2.0, bend).x(), 1e-6);
    const auto cuts = corner_cuts(decisions);
    ASSERT_EQ(cuts.size(), 2u);
    for (const auto& cut : cuts) {
      EXPECT_EQ(cut.action, rules::Action::trim);
      EXPECT_EQ(cut.origin, "element");
      ASSERT_TRUE(cut.element && cut.matched_element);
      EXPECT_NE(*cut.element, *cut.matched_element);
      ASSERT_EQ(cut.before.size(), 4u);
      ASSERT_EQ(cut.after.size(), 4u);
      EXPECT_NE(cut.explanation.find("past its corner"), std::string::npos) << cut.explanation;
      EXPECT_NE(cut.explanation.find("(3.000, 0.000)"), std::string::npos) << cut.explanation;
      EXPECT_NE(cut.explanation.find("7.0 deg"), std::string::npos) << cut.explanation;
    }
    const bool a_cut_first = cuts[0].explanation.find("ran 0.300 m") != std::string::npos;
    EXPECT_NE(cuts[a_cut_first ? 1 : 0].explanation.find("ran 0.150 m"), std::string::npos);
    // Another view of the first facet running past the corner is merged, and the merge stops at the corner: nothing
    // to cut afterwards.
    const auto again =
        apply_observation(state, view_from({0.5, 0}, {3.3, 0}, viewpoint, 0.01, 0.005), 3, options, std::ref(rules));
    ASSERT_EQ(again.decisions.at(0).action, rules::Action::merge);
    EXPECT_TRUE(corner_cuts(again.decisions).empty());
    const auto& merged = again.state.elements.at(*WorldState::element_number(*again.decisions.at(0).element)).segment;
    EXPECT_NEAR(std::max(merged.p0().x(), merged.p1().x()), 3.0, 1e-3);
  }
}

// What is no corner of two facets is not cut: a board standing against a wall at 10° (it meets the wall's line
// inside the wall, 2 m from its end), a T (90°), two views of one wall 2.5° apart that stayed two elements, and a
// facet that runs on 0.6 m past a 7° bend (7.3 cm off the next facet's line there: a wall of its own).
TEST(CornerCutTest, WhatIsNoCornerOfTwoFacetsIsNotCut) {
  struct Case {
    const char* what;
    Eigen::Vector2d a0, a1, b0, b1;
  };
  const double bend = 7 * kDeg;
  const std::vector<Case> cases = {
      {"a board against a wall", {0, 0}, {6, 0}, {2, 0}, {2 + 1.5 * std::cos(10 * kDeg), 1.5 * std::sin(10 * kDeg)}},
      {"a T", {0, 0}, {6, 0}, {3, 0.05}, {3, -3}},
      {"two views 2.5 deg apart", {0, 0}, {3.3, 0}, on_next_facet(-0.3, 2.5 * kDeg), on_next_facet(2.0, 2.5 * kDeg)},
      {"a wall running on far past a bend", {0, 0}, {3.6, 0}, on_next_facet(0, bend), on_next_facet(2.0, bend)},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    WorldOptions options;
    JoiningRules rules;
    rules.join_action = "ignore";  // two elements stay two, whatever the join gate says
    std::vector<DecisionRecord> decisions;
    const auto state = add_views(
        WorldState{}, {view_from(c.a0, c.a1, {1, 3}, 0.01, 0.005), view_from(c.b0, c.b1, {1, 3}, 0.01, 0.005)}, options,
        rules, &decisions);
    EXPECT_TRUE(corner_cuts(decisions).empty()) << corner_cuts(decisions).front().explanation;
    double length = 0;
    for (const auto& [number, e] : state.elements) length += e.segment.length_m();
    EXPECT_NEAR(length, (c.a1 - c.a0).norm() + (c.b1 - c.b0).norm(), 1e-6);
  }
  // The bend of the two facets above, but seen from either side of it (two faces, not a corner), or posted by a
  // client (whose elements only the client changes, as the grid trim leaves them).
  const auto first_part = [&](Eigen::Vector2d viewpoint, bool client) {
    auto obs = view_from({0, 0}, {3.3, 0}, viewpoint, 0.01, 0.005, !client);
    if (client) obs.origin = "client";
    return obs;
  };
  const auto second_part = [&](Eigen::Vector2d viewpoint, bool client) {
    auto obs = view_from(on_next_facet(-0.15, bend), on_next_facet(2.0, bend), viewpoint, 0.01, 0.005, !client);
    if (client) obs.origin = "client";
    return obs;
  };
  for (const bool client : {false, true}) {
    SCOPED_TRACE(client ? "posted by a client" : "seen from either side");
    WorldOptions options;
    JoiningRules rules;
    std::vector<DecisionRecord> decisions;
    add_views(
        WorldState{},
        {first_part({1, 3}, client), second_part(client ? Eigen::Vector2d(1, 3) : Eigen::Vector2d(4, -3), client)},
        options, rules, &decisions);
    EXPECT_TRUE(corner_cuts(decisions).empty()) << corner_cuts(decisions).front().explanation;
  }
}

}  // namespace
}  // namespace wm::world
