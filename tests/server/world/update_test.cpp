#include "server/world/update.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <iostream>
#include <numbers>
#include <random>

#include "tests/support/lab_plan.h"

namespace wm::world {
namespace {

apriori::FloorPlan lab() { return testing::lab_plan(); }

Observation observe(std::initializer_list<std::pair<Eigen::Vector2d, Eigen::Vector2d>> segments,
                    const WorldOptions& o) {
  Observation obs;
  obs.observer = "robot";
  for (const auto& [a, b] : segments) {
    auto s = fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
    s.line.cov = midpoint_line_cov(s, o.default_offset_sigma_m, o.default_angle_sigma_rad);
    obs.segments.push_back({s});
  }
  return obs;
}

// Answers a fixed action, and records what the rules were asked.
struct FixedRules {
  std::string action;
  std::vector<rules::DecisionQuery> asked;
  rules::Decision operator()(const rules::DecisionQuery& q) {
    asked.push_back(q);
    return {action, "test_rule", "because the test says so", false};
  }
};

TEST(UpdateTest, QueryNamesTheMatchedEdgeAndItsObject) {
  WorldOptions options;
  const auto start = apply_floor_plan(WorldState{}, lab(), options).state;
  FixedRules rules{"delete", {}};
  const auto result =
      apply_observation(start, observe({{{4, 10.01}, {9, 10.0}}}, options), 1, options, std::ref(rules));
  ASSERT_EQ(rules.asked.size(), 1u);
  EXPECT_EQ(rules.asked[0].element_id, "wall-n/0");
  EXPECT_EQ(rules.asked[0].object_id, "wall-n");
  EXPECT_GT(rules.asked[0].mahalanobis_sq, 0.0);
  EXPECT_EQ(result.decisions[0].action, rules::Action::confirm);
  EXPECT_EQ(result.state.objects[0].confirmations, 1);
  EXPECT_EQ(result.state.version, start.version + 1);
  EXPECT_EQ(start.objects[0].confirmations, 0) << "the input state must not change";
}

TEST(UpdateTest, LaterSegmentsOfARequestSeeTheEarlierOnes) {
  WorldOptions options;
  FixedRules rules{"add", {}};
  const auto obs = observe({{{10, 3}, {13, 3}}, {{12, 3.001}, {15, 3.0}}}, options);
  const auto first = apply_observation(WorldState{}, obs, 1, options, std::ref(rules));
  // The second segment matched e1; the rules said add, and the element it became lies on e1: asked again (a join).
  ASSERT_EQ(rules.asked.size(), 3u);
  EXPECT_EQ(rules.asked[2].origin, "element");
  EXPECT_FALSE(rules.asked[0].element_id.has_value());
  EXPECT_EQ(rules.asked[1].element_id, "e1");  // the element the first segment added
  EXPECT_FALSE(rules.asked[1].object_id.has_value());
  EXPECT_EQ(first.state.elements.size(), 2u);
}

TEST(UpdateTest, ActionsThatDoNotFitTheMatchFallBackToAdd) {
  WorldOptions options;
  const auto start = apply_floor_plan(WorldState{}, lab(), options).state;
  // "prune" is an action of prune/3 only: from decide/5 it is as unknown as any other atom.
  for (const std::string action : {"frobnicate", "prune"}) {
    FixedRules rules{action, {}};
    const auto result =
        apply_observation(start, observe({{{4, 10.01}, {9, 10.0}}}, options), 1, options, std::ref(rules));
    ASSERT_EQ(result.decisions.size(), 1u);
    EXPECT_EQ(result.decisions[0].action, rules::Action::add) << action;
    EXPECT_EQ(result.decisions[0].rule, "fallback");
    EXPECT_TRUE(result.decisions[0].fallback);
    EXPECT_NE(result.decisions[0].explanation.find(action), std::string::npos);
    EXPECT_EQ(result.state.elements.size(), 1u);
    EXPECT_EQ(result.state.objects[0].confirmations, 0);
  }
  FixedRules rigid{"rigid_adjust", {}};
  const auto unmatched =
      apply_observation(start, observe({{{30, 30}, {31, 31}}}, options), 1, options, std::ref(rigid));
  EXPECT_TRUE(unmatched.decisions[0].fallback);
  FixedRules merge{"merge", {}};
  const auto nothing = apply_observation(start, observe({{{30, 30}, {31, 31}}}, options), 1, options, std::ref(merge));
  EXPECT_TRUE(nothing.decisions[0].fallback) << "merge without a match";
}

TEST(UpdateTest, MergeIntoACadEdgeStartsAnElementFromTheDrawingAndKeepsTheDrawing) {
  WorldOptions options;
  const auto start = apply_floor_plan(WorldState{}, lab(), options).state;
  FixedRules merge{"merge", {}};
  const auto obs = observe({{{4, 10.01}, {9, 10.0}}}, options);
  const auto result = apply_observation(start, obs, 1, options, std::ref(merge));
  ASSERT_EQ(result.decisions.size(), 1u);
  const auto& d = result.decisions[0];
  EXPECT_EQ(d.action, rules::Action::merge);
  EXPECT_FALSE(d.fallback);
  EXPECT_EQ(d.element, "e1");
  EXPECT_EQ(d.matched_element, "wall-n/0");
  ASSERT_EQ(result.state.elements.size(), 1u);
  const auto& element = result.state.elements.at(1);
  EXPECT_EQ(element.support, 2);
  // Fused with the drawn edge: its direction more certain than the observation's alone (σ 0.01 rad; the floor is
  // 0.0087), and the union of both extents.
  EXPECT_LT(element.segment.line.cov(1, 1), obs.segments[0].segment.line.cov(1, 1));
  EXPECT_NEAR(element.segment.length_m(), 20.0, 1e-4);
  EXPECT_EQ(result.state.objects[0].body.pose().x_m, start.objects[0].body.pose().x_m);
  ASSERT_EQ(d.before.size(), 6u);
  ASSERT_EQ(d.after.size(), 6u);
  EXPECT_LT(d.after[2], d.before[2] + obs.segments[0].segment.line.cov(0, 0));
}

TEST(UpdateTest, IgnoreChangesNothing) {
  WorldOptions options;
  const auto start = apply_floor_plan(WorldState{}, lab(), options).state;
  FixedRules ignore{"ignore", {}};
  const auto result = apply_observation(start, observe({{{4, 10.01}, {9, 10.0}}, {{30, 30}, {31, 31}}}, options), 1,
                                        options, std::ref(ignore));
  EXPECT_EQ(result.decisions[0].action, rules::Action::ignore);
  EXPECT_FALSE(result.decisions[1].fallback);
  EXPECT_TRUE(result.state.elements.empty());
  EXPECT_EQ(result.state.objects[0].confirmations, 0);
  EXPECT_TRUE(result.changed_objects.empty());
}

TEST(UpdateTest, PruneRemovesNamedElementsWithADecisionEach) {
  WorldOptions options;
  FixedRules add{"add", {}};
  auto result = apply_observation(WorldState{}, observe({{{0, 0}, {2, 0}}, {{0, 5}, {2, 5}}}, options), 1, options,
                                  std::ref(add));
  ASSERT_EQ(result.state.elements.size(), 2u);
  apply_prune(result, {{"e2", "unconfirmed_pruned", "seen once"}, {"e99", "x", "unknown ids are skipped"}}, 1, "robot");
  EXPECT_EQ(result.state.elements.size(), 1u);
  EXPECT_TRUE(result.state.elements.count(1));
  EXPECT_EQ(result.removed_elements, std::set<std::int64_t>{2});
  EXPECT_EQ(result.changed_elements, std::set<std::int64_t>{1});
  ASSERT_EQ(result.decisions.size(), 3u);
  EXPECT_EQ(result.decisions[2].action, rules::Action::prune);
  EXPECT_EQ(result.decisions[2].rule, "unconfirmed_pruned");
  EXPECT_EQ(result.decisions[2].element, "e2");
  EXPECT_EQ(result.decisions[2].seq, 3);
  EXPECT_EQ(result.decisions[2].index, -1);
}

TEST(UpdateTest, RecordedQueryAsksTheOriginalQuestionAgain) {
  WorldOptions options;
  const auto start = apply_floor_plan(WorldState{}, lab(), options).state;
  FixedRules add{"add", {}};
  auto obs = observe({{{4, 10.01}, {9, 10.0}}}, options);
  obs.sensor = "laser";
  obs.origin = "scan";
  const auto result = apply_observation(start, obs, 1, options, std::ref(add));
  const auto again = result.decisions[0].query();
  EXPECT_EQ(again.element_id, add.asked[0].element_id);
  EXPECT_EQ(again.object_id, add.asked[0].object_id);
  EXPECT_DOUBLE_EQ(again.mahalanobis_sq, add.asked[0].mahalanobis_sq);
  EXPECT_NEAR(again.rho_m, add.asked[0].rho_m, 1e-12);
  EXPECT_NEAR(again.phi_rad, add.asked[0].phi_rad, 1e-12);
  EXPECT_NEAR(again.length_m, add.asked[0].length_m, 1e-9);
  EXPECT_EQ(again.sensor, "laser");
  EXPECT_EQ(again.origin, "scan");
  EXPECT_EQ(result.decisions[0].element, "e1") << "the produced element is kept apart from the match";
}

TEST(UpdateTest, CollinearWallsAcrossADoorwayStayApart) {
  WorldOptions options;
  FixedRules rules{"add", {}};
  auto state = apply_observation(WorldState{}, observe({{{0, 5}, {4, 5}}}, options), 1, options, std::ref(rules)).state;
  state = apply_observation(state, observe({{{5, 5}, {9, 5}}}, options), 2, options, std::ref(rules)).state;
  EXPECT_FALSE(rules.asked[1].element_id.has_value()) << "a 1 m doorway must not be bridged";
  FixedRules merge{"merge", {}};
  const auto result = apply_observation(state, observe({{{1, 5.002}, {3, 5.0}}}, options), 3, options, std::ref(merge));
  EXPECT_EQ(merge.asked[0].element_id, "e1");
  EXPECT_EQ(result.decisions[0].action, rules::Action::merge);
  EXPECT_EQ(result.state.elements.at(1).support, 2);
  EXPECT_EQ(result.state.elements.at(2).support, 1);
}

// Answers `merge` to scan lines and `join_action` to the maintenance question (origin "element").
struct JoiningRules {
  std::string join_action = "merge";
  std::vector<rules::DecisionQuery> asked;
  rules::Decision operator()(const rules::DecisionQuery& q) {
    asked.push_back(q);
    if (q.origin == "element") return {join_action, "elements_merged", "one wall", false};
    return {q.element_id ? "merge" : "add", "test_rule", "because", false};
  }
};

TEST(UpdateTest, AnObservationThatBridgesTwoElementsJoinsThemIntoOne) {
  WorldOptions options;
  JoiningRules rules;
  // Two views of one wall with a 0.5 m gap between them (more than max_gap_m: two elements).
  auto state = apply_observation(WorldState{}, observe({{{0, 2}, {2, 2}}, {{2.5, 2}, {4.5, 2}}}, options), 1, options,
                                 std::ref(rules))
                   .state;
  ASSERT_EQ(state.elements.size(), 2u);
  // A view across the gap merges into e1, which then lies on e2: the rules are asked, and the two become one.
  const auto result =
      apply_observation(state, observe({{{1.5, 2.005}, {3.0, 2.005}}}, options), 2, options, std::ref(rules));
  ASSERT_EQ(result.state.elements.size(), 1u);
  // The view matched one of the two (equally close); that one absorbed the other.
  const auto& [kept_number, joined] = *result.state.elements.begin();
  const std::int64_t other_number = 3 - kept_number;
  EXPECT_NEAR(joined.segment.length_m(), 4.5, 1e-3);
  EXPECT_EQ(joined.support, 3);
  EXPECT_NEAR(joined.moments.weight, 2.0 + 2.0 + 1.5, 1e-12);
  EXPECT_EQ(result.removed_elements, std::set<std::int64_t>{other_number});
  EXPECT_EQ(result.changed_elements, std::set<std::int64_t>{kept_number});
  ASSERT_EQ(result.decisions.size(), 2u);
  const auto& join = result.decisions[1];
  EXPECT_EQ(join.index, -1);
  EXPECT_EQ(join.origin, "element");
  EXPECT_EQ(join.rule, "elements_merged");
  EXPECT_EQ(join.element, joined.id());
  EXPECT_EQ(join.before.size(), 6u);
  EXPECT_EQ(join.after.size(), 6u);
  const auto& question = rules.asked.back();
  EXPECT_EQ(question.origin, "element");
  EXPECT_EQ(question.observer, "e" + std::to_string(other_number));
  EXPECT_EQ(question.element_id, joined.id());
  EXPECT_NEAR(question.length_m, 2.0, 1e-9);

  // Rules that keep elements apart are obeyed: both stay, and nothing is logged for the refusal.
  JoiningRules apart{"add", {}};
  const auto kept =
      apply_observation(state, observe({{{1.5, 2.005}, {3.0, 2.005}}}, options), 2, options, std::ref(apart));
  EXPECT_EQ(kept.state.elements.size(), 2u);
  EXPECT_EQ(kept.decisions.size(), 1u);
}

TEST(UpdateTest, ASingleTiltedViewLyingAlongAWallIsJoinedIntoItAsAPiece) {
  WorldOptions options;
  JoiningRules rules;
  auto wall = apply_observation(WorldState{}, observe({{{0, 0}, {6, 0}}}, options), 1, options, std::ref(rules)).state;
  ASSERT_EQ(wall.elements.size(), 1u);
  const auto before = wall.elements.at(1).segment;
  // 0.4 m tilted by 7°: the direction gate refuses it, but it lies within 1.5 cm RMS of the wall, inside its extent.
  const auto result =
      apply_observation(wall, observe({{{2.0, -0.02}, {2.4, 0.03}}}, options), 2, options, std::ref(rules));
  EXPECT_EQ(rules.asked[rules.asked.size() - 2].element_id, std::nullopt) << "the gate should refuse the view";
  ASSERT_EQ(result.state.elements.size(), 1u);
  const Element& joined = result.state.elements.at(1);
  EXPECT_EQ(joined.support, 2);
  EXPECT_EQ(result.removed_elements, std::set<std::int64_t>{2});
  ASSERT_EQ(result.decisions.size(), 2u);
  EXPECT_EQ(result.decisions[1].rule, "elements_merged");
  EXPECT_EQ(rules.asked.back().observer, "e2");
  EXPECT_EQ(rules.asked.back().element_id, "e1");
  // The piece adds its points, not its direction: the wall keeps its extent and turns by a hair.
  EXPECT_NEAR(joined.segment.length_m(), 6.0, 1e-6);
  EXPECT_LT(std::abs(std::remainder(joined.segment.line.phi_rad - before.line.phi_rad, std::numbers::pi)), 0.002);

  // 0.4 m at 35° leaves the band (RMS 6.6 cm): it stays an element of its own.
  JoiningRules again;
  const auto apart =
      apply_observation(wall, observe({{{2.0, -0.115}, {2.33, 0.115}}}, options), 2, options, std::ref(again));
  EXPECT_EQ(apart.state.elements.size(), 2u);
  // Two views of the tilted piece (support 2) are a direction the data holds, not a 3σ view: also left alone.
  auto twice = wall;
  auto piece =
      apply_observation(WorldState{}, observe({{{2.0, -0.02}, {2.4, 0.03}}}, options), 1, options, std::ref(again))
          .state.elements.at(1);
  piece.number = 2;
  piece.support = 2;
  twice.elements.put(piece);
  twice.next_element_number = 3;
  const auto grown =
      apply_observation(twice, observe({{{0.0, 0.0}, {6.0, 0.0}}}, options), 3, options, std::ref(again));
  EXPECT_EQ(grown.state.elements.size(), 2u);
  EXPECT_TRUE(grown.removed_elements.empty());
  EXPECT_EQ(grown.state.elements.at(2).support, 2);
  EXPECT_EQ(grown.state.elements.at(1).support, 2) << "the view merged into the wall";
}

TEST(UpdateTest, AnElementBuiltFromABentWallTakesNoMoreObservations) {
  WorldOptions options;
  JoiningRules rules;
  auto state =
      apply_observation(WorldState{}, observe({{{0, 0}, {10, 0}}}, options), 1, options, std::ref(rules)).state;
  // What it was built from bows 10 cm out at the middle (RMS ≈ 2.9 cm about the best line).
  auto element = state.elements.at(1);
  element.moments =
      fusion::SegmentMoments::of(fusion::LineSegment::from_points({0, 0}, {5, 0.1}, Eigen::Matrix2d::Identity())) +
      fusion::SegmentMoments::of(fusion::LineSegment::from_points({5, 0.1}, {10, 0}, Eigen::Matrix2d::Identity()));
  EXPECT_NEAR(element.moments.rms_offset_m(), 0.1 / std::sqrt(12.0), 2e-3);
  state.elements.put(element);
  options.max_straightness_rms_m = 0.02;
  // The fixed allowance alone: a 1 cm view's own spread would allow 2.9 cm, the element's scatter 4.4 cm.
  options.straightness_sigmas = 0.0;
  options.join_scatter_factor = 0.0;
  const auto result = apply_observation(state, observe({{{4, 0.0}, {6, 0.0}}}, options), 2, options, std::ref(rules));
  // Neither a candidate for the view nor joined with the element the view became.
  EXPECT_FALSE(rules.asked.back().element_id.has_value()) << "the bent element is no candidate";
  EXPECT_EQ(result.state.elements.size(), 2u);
  options.max_straightness_rms_m = 0.05;
  const auto taken = apply_observation(state, observe({{{4, 0.0}, {6, 0.0}}}, options), 2, options, std::ref(rules));
  EXPECT_EQ(rules.asked.back().element_id, "e1");
  EXPECT_EQ(taken.state.elements.size(), 1u);
}

// One segment seen by a sensor at `viewpoint` (its facing set) with the midpoint-form σ a pose of that quality
// gives; `facing` false leaves the facing unknown, as for a posted segment.
Observation view_from(Eigen::Vector2d a, Eigen::Vector2d b, Eigen::Vector2d viewpoint, double offset_sigma_m,
                      double angle_sigma_rad, bool facing = true) {
  Observation obs;
  obs.observer = "robot";
  obs.origin = "scan";
  auto s = fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
  s.line.cov = midpoint_line_cov(s, offset_sigma_m, angle_sigma_rad);
  obs.segments.push_back({s, facing ? std::optional<double>(facing_toward(s, viewpoint)) : std::nullopt});
  return obs;
}

TEST(FacingTest, FacingPointsToTheSensorsSideWhicheverWayTheLineIsWritten) {
  const auto s = fusion::LineSegment::from_points({0, 1}, {4, 1}, Eigen::Matrix2d::Identity());
  const auto r = fusion::LineSegment::from_points({4, 1}, {0, 1}, Eigen::Matrix2d::Identity());
  EXPECT_NEAR(std::cos(facing_toward(s, {2, 3})), 0.0, 1e-12);
  EXPECT_NEAR(std::sin(facing_toward(s, {2, 3})), 1.0, 1e-12);
  EXPECT_NEAR(std::sin(facing_toward(r, {2, 3})), 1.0, 1e-12);
  EXPECT_NEAR(std::sin(facing_toward(s, {2, -3})), -1.0, 1e-12);
  EXPECT_TRUE(faces_agree(facing_toward(s, {2, 3}), facing_toward(r, {1, 2})));
  EXPECT_FALSE(faces_agree(facing_toward(s, {2, 3}), facing_toward(s, {2, -3})));
  EXPECT_TRUE(faces_agree(std::nullopt, facing_toward(s, {2, -3})));
}

// A 12 cm wall seen from both sides by a robot whose pose is known to σ 5 cm across the view: the two faces pass
// every gate, and only the side they were seen from tells them apart.
TEST(FacingTest, TheTwoFacesOfAThickWallSeenFromEitherSideStayTwoElements) {
  WorldOptions options;
  JoiningRules rules;
  const auto below = view_from({0, 0}, {6, 0}, {3, -2}, 0.05, 0.0087);
  const auto above = view_from({0, 0.12}, {6, 0.12}, {3, 2.12}, 0.05, 0.0087);
  auto state = apply_observation(WorldState{}, below, 1, options, std::ref(rules)).state;
  const auto two = apply_observation(state, above, 2, options, std::ref(rules));
  ASSERT_EQ(two.state.elements.size(), 2u) << "the faces of a 12 cm wall became one element";
  EXPECT_NEAR(two.state.elements.at(1).segment.line.signed_distance({3, 0}), 0.0, 1e-9);
  EXPECT_NEAR(std::abs(two.state.elements.at(2).segment.line.signed_distance({3, 0.12})), 0.0, 1e-9);
  EXPECT_NEAR(std::sin(*two.state.elements.at(1).facing_rad), -1.0, 1e-9);
  EXPECT_NEAR(std::sin(*two.state.elements.at(2).facing_rad), 1.0, 1e-9);
  // The same views without their facing (posted segments): nothing tells them apart, and they are one element.
  const auto below_posted = view_from({0, 0}, {6, 0}, {3, -2}, 0.05, 0.0087, false);
  const auto above_posted = view_from({0, 0.12}, {6, 0.12}, {3, 2.12}, 0.05, 0.0087, false);
  state = apply_observation(WorldState{}, below_posted, 1, options, std::ref(rules)).state;
  EXPECT_EQ(apply_observation(state, above_posted, 2, options, std::ref(rules)).state.elements.size(), 1u);
}

TEST(FacingTest, AThinSurfaceSeenFromBothSidesIsOneElementThatFacesBothWays) {
  WorldOptions options;
  JoiningRules rules;
  auto state =
      apply_observation(WorldState{}, view_from({0, 0}, {6, 0}, {3, -2}, 0.01, 0.0035), 1, options, std::ref(rules))
          .state;
  // 1 cm from the first, seen from the other side: no candidate for the view, then joined as one thin surface.
  const auto joined =
      apply_observation(state, view_from({0, 0.01}, {6, 0.01}, {3, 2}, 0.01, 0.0035), 2, options, std::ref(rules));
  ASSERT_EQ(joined.state.elements.size(), 1u);
  const Element& surface = (*joined.state.elements.begin()).second;
  EXPECT_FALSE(surface.facing_rad.has_value());
  EXPECT_EQ(joined.decisions.back().rule, "elements_merged");
  // From now on a view from either side merges straight into it.
  for (const auto& viewpoint : {Eigen::Vector2d(3, -2), Eigen::Vector2d(3, 2)}) {
    const auto more = apply_observation(joined.state, view_from({1, 0.005}, {5, 0.005}, viewpoint, 0.01, 0.0035), 3,
                                        options, std::ref(rules));
    EXPECT_EQ(more.state.elements.size(), 1u);
    EXPECT_EQ(more.decisions.front().matched_element, surface.id());
  }
  // 5 cm apart is more than thin_surface_m: two faces.
  const auto thick =
      apply_observation(state, view_from({0, 0.05}, {6, 0.05}, {3, 2}, 0.01, 0.0035), 2, options, std::ref(rules));
  EXPECT_EQ(thick.state.elements.size(), 2u);
}

// A 17 m wall: a second view turned by 1.5° (3σ of a 0.5° heading, 2σ of the difference of two) spreads the two to
// 6.4 cm RMS, more than the fixed 5 cm, but within what the view's own covariance allows.
TEST(UpdateTest, AViewOfALongWallPostedWithANoisyHeadingIsTakenIn) {
  WorldOptions options;
  JoiningRules rules;
  const double tilt = 1.5 * std::numbers::pi / 180;
  const auto first = view_from({0, 0}, {17, 0}, {8.5, -3}, 0.03, 0.0087);
  const auto second = view_from({0, -0.5 * 17 * std::sin(tilt)}, {17 * std::cos(tilt), 0.5 * 17 * std::sin(tilt)},
                                {8.5, -3}, 0.03, 0.0087);
  const auto state = apply_observation(WorldState{}, first, 1, options, std::ref(rules)).state;
  const auto spread = (state.elements.at(1).moments + fusion::SegmentMoments::of(second.segments[0].segment));
  ASSERT_GT(spread.rms_offset_m(), options.max_straightness_rms_m);
  const auto taken = apply_observation(state, second, 2, options, std::ref(rules));
  EXPECT_EQ(taken.state.elements.size(), 1u);
  EXPECT_EQ(taken.decisions.front().matched_element, "e1");
  // Held to the fixed 5 cm alone, the view is another wall.
  options.straightness_sigmas = 0.0;
  EXPECT_EQ(apply_observation(state, second, 2, options, std::ref(rules)).state.elements.size(), 2u);
}

TEST(UpdateTest, MidpointCovarianceCarriesTheLeverArm) {
  auto s = fusion::LineSegment::from_points({10, 3}, {14, 3}, Eigen::Matrix2d::Identity());
  const auto c = midpoint_line_cov(s, 0.01, 0.02);
  const double t_mid = 0.5 * (s.t0_m + s.t1_m);
  EXPECT_NEAR(std::abs(t_mid), 12.0, 1e-9);
  EXPECT_NEAR(c(1, 1), 4e-4, 1e-15);
  EXPECT_NEAR(c(0, 1), t_mid * 4e-4, 1e-12);
  EXPECT_NEAR(c(0, 0), 1e-4 + t_mid * t_mid * 4e-4, 1e-12);
}

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

// --- A not_deformable table far from the world origin, moved, seen again by simulated scans. ---

// Answers as the shipped rules do: a not_deformable object's edge → rigid_adjust, a solid object's → delete, an
// element → merge, nothing → add.
struct ShippedLikeRules {
  apriori::FloorPlan plan;
  rules::Decision operator()(const rules::DecisionQuery& q) const {
    if (q.origin == "element") return {"merge", "elements_merged", "one wall", false};
    if (!q.element_id) return {"add", "unmatched_added", "nothing matched", false};
    if (!q.object_id) return {"merge", "unknown_element_merged", "an element", false};
    for (const auto& o : plan.objects)
      if (o.id == *q.object_id) {
        if (o.has_attribute("not_deformable")) return {"rigid_adjust", "not_deformable_rigid", "moved", false};
        return {"delete", "solid_confirmed", "confirmed", false};
      }
    return {"add", "unmatched_added", "unknown object", false};
  }
};

constexpr double kDeg = std::numbers::pi / 180.0;
const fusion::Pose2D kTablePose{24.0, 7.0, 0.2};  // 25 m from the world origin

apriori::PlanObject far_table() {
  apriori::PlanObject table;
  table.id = "table-far";
  table.kind = "table";
  table.attributes = {"not_deformable"};
  table.pose = kTablePose;
  table.polygon = {{-0.6, -0.4}, {0.6, -0.4}, {0.6, 0.4}, {-0.6, 0.4}};  // counter-clockwise
  return table;
}

// A segment seen with σ = 1 cm on each end, with the covariance that noise gives (midpoint form).
fusion::LineSegment noisy_segment(Eigen::Vector2d a, Eigen::Vector2d b, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, 0.01);
  a += Eigen::Vector2d(noise(rng), noise(rng));
  b += Eigen::Vector2d(noise(rng), noise(rng));
  auto s = fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
  s.line.cov = midpoint_line_cov(s, 0.01 / std::sqrt(2.0), 0.01 * std::sqrt(2.0) / s.length_m());
  return s;
}

// The sides of `table` standing at `pose` that a robot at `viewpoint` sees (outward normal toward it), each a
// partial view (up to 5 cm short at either end).
Observation table_scan(const apriori::PlanObject& table, const fusion::Pose2D& pose, const Eigen::Vector2d& viewpoint,
                       std::mt19937& rng) {
  std::uniform_real_distribution<double> trim(0.0, 0.05);
  Observation obs;
  obs.observer = "robot";
  obs.origin = "scan";
  const auto& poly = table.polygon;
  for (std::size_t k = 0; k < poly.size(); ++k) {
    const Eigen::Vector2d a = pose.transform_point(poly[k]), b = pose.transform_point(poly[(k + 1) % poly.size()]);
    const Eigen::Vector2d d = (b - a).normalized();
    if (Eigen::Vector2d(d.y(), -d.x()).dot(viewpoint - a) <= 0.0) continue;
    obs.segments.push_back({noisy_segment(a + trim(rng) * d, b - trim(rng) * d, rng)});
  }
  return obs;
}

struct TableRun {
  double position_error_m = 0, angle_error_rad = 0;
  std::size_t elements = 0;
};

// Eight scans from the four diagonals around the table (each sees two sides), 3 m from its centre.
TableRun run_moved_table(double shift_m, double turn_rad, unsigned seed) {
  WorldOptions options;
  const auto table = far_table();
  ShippedLikeRules rules{{"far", {table}}};
  auto state = apply_floor_plan(WorldState{}, rules.plan, options).state;
  const fusion::Pose2D truth{kTablePose.x_m + shift_m * std::cos(0.5), kTablePose.y_m + shift_m * std::sin(0.5),
                             kTablePose.theta_rad + turn_rad};
  std::mt19937 rng(seed);
  for (int scan = 0; scan < 8; ++scan) {
    const double bearing = std::numbers::pi / 4 + scan * std::numbers::pi / 2;
    const Eigen::Vector2d viewpoint =
        Eigen::Vector2d(truth.x_m, truth.y_m) + 3.0 * Eigen::Vector2d(std::cos(bearing), std::sin(bearing));
    state = apply_observation(state, table_scan(table, truth, viewpoint, rng), scan + 1, options, rules).state;
  }
  const auto& pose = state.objects[0].body.pose();
  return {std::hypot(pose.x_m - truth.x_m, pose.y_m - truth.y_m),
          std::abs(std::remainder(pose.theta_rad - truth.theta_rad, 2 * std::numbers::pi)), state.elements.size()};
}

TEST(RigidAdjustTest, AMovedTableFarFromTheOriginEndsWhereItStands) {
  for (const double shift : {0.1, 0.3, 0.5})
    for (const double turn : {5.0, 10.0, 20.0}) {
      const TableRun run = run_moved_table(shift, turn * kDeg, 7);
      std::cout << "[figures] table moved " << shift << " m, " << turn << " deg: ends " << run.position_error_m * 100
                << " cm, " << run.angle_error_rad / kDeg << " deg from the truth, " << run.elements
                << " elements added\n";
      EXPECT_LT(run.position_error_m, 0.03) << shift << " m, " << turn << " deg";
      EXPECT_LT(run.angle_error_rad, 1.0 * kDeg) << shift << " m, " << turn << " deg";
      EXPECT_EQ(run.elements, 0u) << "the table's sides must not become walls (" << shift << " m, " << turn << " deg)";
    }
}

TEST(RigidAdjustTest, ATableBesideAWallIsNotDraggedByTheWallsLines) {
  WorldOptions options;
  const auto table = far_table();
  ShippedLikeRules rules{{"far", {table}}};
  auto state = apply_floor_plan(WorldState{}, rules.plan, options).state;
  // The wall runs along the table's top side (local y = 0.4), 2 cm outside it, 6 m long. Every other scan sees
  // only the wall, whole (a laser above the table top); the others see the table's bottom and right sides and the
  // wall in the two pieces either side of the table.
  const auto& pose = kTablePose;
  const Eigen::Vector2d wall_a = pose.transform_point({-3.0, 0.42}), wall_b = pose.transform_point({3.0, 0.42});
  const Eigen::Vector2d viewpoint = pose.transform_point({1.5, -3.0});
  std::mt19937 rng(11);
  for (int scan = 0; scan < 8; ++scan) {
    Observation obs;
    obs.observer = "robot";
    if (scan % 2 == 0) {
      obs.segments.push_back({noisy_segment(wall_a, wall_b, rng)});
    } else {
      obs = table_scan(table, pose, viewpoint, rng);
      obs.segments.push_back({noisy_segment(wall_a, pose.transform_point({-0.75, 0.42}), rng)});
      obs.segments.push_back({noisy_segment(pose.transform_point({0.75, 0.42}), wall_b, rng)});
    }
    const fusion::Pose2D before = state.objects[0].body.pose();
    const auto result = apply_observation(state, obs, scan + 1, options, rules);
    for (const auto& d : result.decisions)
      if ((d.p1 - d.p0).norm() > 1.5) {
        EXPECT_NE(d.matched_object, "table-far") << "scan " << scan;
      }
    state = result.state;
    const fusion::Pose2D& after = state.objects[0].body.pose();
    if (scan % 2 == 0) {
      EXPECT_EQ(after.x_m, before.x_m) << "the wall alone moved the table in scan " << scan;
      EXPECT_EQ(after.y_m, before.y_m);
      EXPECT_EQ(after.theta_rad, before.theta_rad);
    }
  }
  const auto& body = state.objects[0].body.pose();
  const double moved = std::hypot(body.x_m - pose.x_m, body.y_m - pose.y_m);
  const double turned = std::abs(std::remainder(body.theta_rad - pose.theta_rad, 2 * std::numbers::pi));
  std::cout << "[figures] table beside a wall: moved " << moved * 100 << " cm, turned " << turned / kDeg << " deg\n";
  // What the views of its own sides (1 cm noise) leave, no more.
  EXPECT_LT(moved, 0.01);
  EXPECT_LT(turned, 0.5 * kDeg);
  // The wall is a wall of its own.
  bool wall_element = false;
  for (const auto& [number, element] : state.elements) wall_element |= element.segment.length_m() > 5.0;
  EXPECT_TRUE(wall_element);
}

}  // namespace
}  // namespace wm::world

// The decision log, JSON and the knowledge base speak wire names; every Action has one and reads back as itself.
TEST(ActionTest, WireNamesRoundTrip) {
  for (const auto action :
       {wm::rules::Action::confirm, wm::rules::Action::merge, wm::rules::Action::rigid_adjust, wm::rules::Action::add,
        wm::rules::Action::ignore, wm::rules::Action::prune, wm::rules::Action::trim})
    EXPECT_EQ(wm::rules::parse_action(wm::rules::wire_name(action)), action);
  EXPECT_EQ(wm::rules::wire_name(wm::rules::Action::confirm), "delete");  // the seed paper's word, kept on the wire
  EXPECT_FALSE(wm::rules::parse_action("confirm").has_value());
  EXPECT_FALSE(wm::rules::parse_action("").has_value());
}

namespace wm::world {
namespace {

// A table carried 0.3 m / 10°, seen first from one side at a time (each side alone: beyond its gate, an element of
// its own), then from a corner (two sides in one scan): found by its shape, moved where it stands, and the elements
// its one-sided views became are taken back (prune, rule object_found).
TEST(RigidAdjustTest, ATableSeenOneSideAtATimeIsFoundAndItsSideElementsAreTakenBack) {
  WorldOptions options;
  const auto table = far_table();
  ShippedLikeRules rules{{"far", {table}}};
  auto state = apply_floor_plan(WorldState{}, rules.plan, options).state;
  const fusion::Pose2D truth{kTablePose.x_m + 0.3 * std::cos(0.5), kTablePose.y_m + 0.3 * std::sin(0.5),
                             kTablePose.theta_rad + 10 * kDeg};
  std::mt19937 rng(5);
  // Straight in front of the long bottom side, then of the right side: one side per scan.
  for (const Eigen::Vector2d& local : {Eigen::Vector2d(0.0, -3.0), Eigen::Vector2d(3.0, 0.0)}) {
    auto obs = table_scan(table, truth, truth.transform_point(local), rng);
    ASSERT_EQ(obs.segments.size(), 1u);
    state = apply_observation(state, obs, 1, options, rules).state;
  }
  ASSERT_EQ(state.elements.size(), 2u) << "each side alone became an element";
  // From the corner between them: two sides in one scan.
  const auto result =
      apply_observation(state, table_scan(table, truth, truth.transform_point({3.0, -3.0}), rng), 3, options, rules);
  const auto& pose = result.state.objects[0].body.pose();
  EXPECT_LT(std::hypot(pose.x_m - truth.x_m, pose.y_m - truth.y_m), 0.03);
  EXPECT_LT(std::abs(std::remainder(pose.theta_rad - truth.theta_rad, 2 * std::numbers::pi)), 1.0 * kDeg);
  EXPECT_TRUE(result.state.elements.empty()) << "the sides' elements are taken back";
  std::size_t taken_back = 0;
  for (const auto& d : result.decisions)
    if (d.rule == "object_found") {
      ++taken_back;
      EXPECT_EQ(d.action, rules::Action::prune);
      EXPECT_EQ(d.object, "table-far");
    }
  EXPECT_EQ(taken_back, 2u);
}

}  // namespace
}  // namespace wm::world
