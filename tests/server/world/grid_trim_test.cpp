// trim_to_grid against a grid given as a function of the point: which ends are cut, which are not, what is logged
// and what the rules are told.
#include "server/world/grid_trim.h"

#include <gtest/gtest.h>

#include <cmath>

namespace wm::world {
namespace {

Element element_along_x(std::int64_t number, double x0, double x1, double y) {
  Element e;
  e.number = number;
  e.segment = fusion::LineSegment::from_points({x0, y}, {x1, y}, Eigen::Matrix2d::Identity() * 1e-4);
  e.moments = fusion::SegmentMoments::of(e.segment);
  e.support = 5;
  e.origin = "scan";
  e.observer = "robot";
  return e;
}

// A wall from x = 1 to x = 3 on y = 0 that the grid backs; the rest of the plane within x in [-5, 5] is seen free,
// beyond it unknown.
GridEvidence wall_probe(const Eigen::Vector2d& p) {
  if (std::abs(p.y()) <= 0.05 && p.x() >= 1.0 && p.x() <= 3.0) return GridEvidence::backed;
  return std::abs(p.x()) <= 5.0 ? GridEvidence::contrary : GridEvidence::unknown;
}

const Box kEverywhere{-100, -100, 100, 100};

WorldState state_with(std::initializer_list<Element> elements) {
  WorldState state;
  state.version = 7;
  state.last_observation_seq = 11;
  state.last_decision_seq = 40;
  for (const auto& e : elements) state.elements.put(e);
  return state;
}

TEST(GridTrimTest, EndsTheGridSeesThroughAreCutBackToTheBackedPart) {
  const WorldState before = state_with({element_along_x(1, 0.0, 4.0, 0.0)});
  const auto result = trim_to_grid(before, kEverywhere, wall_probe, 12, "grid-trim", {});
  ASSERT_EQ(result.update.decisions.size(), 1u);
  const auto& d = result.update.decisions[0];
  EXPECT_EQ(d.action, rules::Action::trim);
  EXPECT_EQ(d.rule, "grid_trimmed");
  EXPECT_EQ(d.element, "e1");
  EXPECT_EQ(d.seq, 41);
  EXPECT_EQ(d.observation_seq, 12);
  EXPECT_EQ(d.index, -1);
  ASSERT_EQ(d.before.size(), 4u);
  EXPECT_NEAR(std::min(d.before[0], d.before[2]), 0.0, 1e-9);
  EXPECT_NEAR(std::max(d.before[0], d.before[2]), 4.0, 1e-9);
  EXPECT_NE(d.explanation.find("cut from 4.000 m to 2.000 m"), std::string::npos) << d.explanation;

  const Element& trimmed = result.update.state.elements.at(1);
  const double x0 = std::min(trimmed.segment.p0().x(), trimmed.segment.p1().x());
  const double x1 = std::max(trimmed.segment.p0().x(), trimmed.segment.p1().x());
  EXPECT_NEAR(x0, 1.0, 1e-9);
  EXPECT_NEAR(x1, 3.0, 1e-9);
  // Only the extent changes: the line, its covariance, the moments and the support stay.
  const Element& old = before.elements.at(1);
  EXPECT_EQ(trimmed.segment.line.rho_m, old.segment.line.rho_m);
  EXPECT_EQ(trimmed.segment.line.phi_rad, old.segment.line.phi_rad);
  EXPECT_EQ(trimmed.segment.line.cov, old.segment.line.cov);
  EXPECT_EQ(trimmed.moments.weight, old.moments.weight);
  EXPECT_EQ(trimmed.support, 5);
  EXPECT_EQ(result.update.state.version, 8);
  EXPECT_EQ(result.update.state.last_observation_seq, 12);
  EXPECT_EQ(result.update.changed_elements, std::set<std::int64_t>{1});
  // `current` is not changed.
  EXPECT_NEAR(before.elements.at(1).segment.length_m(), 4.0, 1e-9);
  EXPECT_EQ(before.version, 7);
  // The rules hear what the grid said of the kept extent: all of it backed.
  ASSERT_EQ(result.checked.size(), 1u);
  EXPECT_EQ(result.checked[0].number, 1);
  EXPECT_DOUBLE_EQ(result.checked[0].backed, 1.0);
  EXPECT_DOUBLE_EQ(result.checked[0].contrary, 0.0);
}

TEST(GridTrimTest, AnEndInUnknownSpaceStaysAndACutStopsAtTheFirstUnknownSample) {
  // From x = 1 (backed) to x = 7: beyond x = 5 the grid knows nothing, so the end at 7 is not cut.
  const auto result =
      trim_to_grid(state_with({element_along_x(2, 1.0, 7.0, 0.0)}), kEverywhere, wall_probe, 12, "grid-trim", {});
  EXPECT_TRUE(result.update.decisions.empty());
  EXPECT_EQ(result.update.state.version, 7);
  ASSERT_EQ(result.checked.size(), 1u);
  EXPECT_NEAR(result.checked[0].backed, 2.0 / 6.0, 0.02);
  EXPECT_NEAR(result.checked[0].contrary, 2.0 / 6.0, 0.02);
}

TEST(GridTrimTest, AnElementTheGridBacksNowhereIsLeftWholeForTheRules) {
  const auto result =
      trim_to_grid(state_with({element_along_x(3, -4.0, -1.0, 2.0)}), kEverywhere, wall_probe, 12, "grid-trim", {});
  EXPECT_TRUE(result.update.decisions.empty());
  ASSERT_EQ(result.checked.size(), 1u);
  EXPECT_DOUBLE_EQ(result.checked[0].backed, 0.0);
  EXPECT_DOUBLE_EQ(result.checked[0].contrary, 1.0);
}

TEST(GridTrimTest, AnElementLeftWholeIsReportedWholeSoTheRulesCanRemoveIt) {
  // From x = 2.97 to x = 4.9: only its first sample touches the wall's end. Its backed part is too short to keep,
  // so it is not cut, and the rules must hear that the grid backs almost none of it.
  const auto result =
      trim_to_grid(state_with({element_along_x(8, 2.97, 4.9, 0.0)}), kEverywhere, wall_probe, 12, "grid-trim", {});
  EXPECT_TRUE(result.update.decisions.empty());
  ASSERT_EQ(result.checked.size(), 1u);
  EXPECT_LT(result.checked[0].backed, 0.05);
  EXPECT_GT(result.checked[0].contrary, 0.9);
}

TEST(GridTrimTest, AClientsElementIsNeverCutButItsSharesAreReported) {
  Element posted = element_along_x(9, 0.0, 4.0, 0.0);
  posted.origin = "client";
  const auto result = trim_to_grid(state_with({posted}), kEverywhere, wall_probe, 12, "grid-trim", {});
  EXPECT_TRUE(result.update.decisions.empty());
  ASSERT_EQ(result.checked.size(), 1u);
  EXPECT_NEAR(result.checked[0].backed, 0.5, 0.02);
  EXPECT_NEAR(result.checked[0].contrary, 0.5, 0.02);
}

TEST(GridTrimTest, CutsShorterThanTheMinimumAndElementsOutsideTheRegionAreLeftAlone) {
  // 3 cm past the wall's end: one sample, cut by default, not when the minimum cut is 10 cm.
  const WorldState past_by_3cm = state_with({element_along_x(4, 1.0, 3.03, 0.0)});
  EXPECT_EQ(trim_to_grid(past_by_3cm, kEverywhere, wall_probe, 12, "grid-trim", {}).update.decisions.size(), 1u);
  GridTrimOptions ten_cm;
  ten_cm.min_trim_m = 0.10;
  EXPECT_TRUE(trim_to_grid(past_by_3cm, kEverywhere, wall_probe, 12, "grid-trim", ten_cm).update.decisions.empty());
  // The region does not reach the element: it is not even looked at.
  auto outside = trim_to_grid(state_with({element_along_x(5, 0.0, 4.0, 0.0)}), Box{10, 10, 20, 20}, wall_probe, 12,
                              "grid-trim", {});
  EXPECT_TRUE(outside.update.decisions.empty());
  EXPECT_TRUE(outside.checked.empty());
  // Several elements: only the one that reaches into seen free space is cut.
  auto both = trim_to_grid(state_with({element_along_x(6, 0.5, 3.0, 0.0), element_along_x(7, 1.0, 3.0, 0.0)}),
                           kEverywhere, wall_probe, 12, "grid-trim", {});
  ASSERT_EQ(both.update.decisions.size(), 1u);
  EXPECT_EQ(both.update.decisions[0].element, "e6");
  EXPECT_EQ(both.checked.size(), 2u);
}

}  // namespace
}  // namespace wm::world
