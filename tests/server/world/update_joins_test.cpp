#include <gtest/gtest.h>

#include <cmath>

#include "server/world/update.h"
#include "tests/server/world/update_test_helpers.h"

namespace wm::world {
namespace {

using namespace update_test_helpers;

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
  EXPECT_TRUE(surface.both_ways);
  EXPECT_EQ(joined.decisions.back().rule, "elements_merged");
  // From now on a view from either side merges straight into it.
  for (const auto& viewpoint : {Eigen::Vector2d(3, -2), Eigen::Vector2d(3, 2)}) {
    const auto more = apply_observation(joined.state, view_from({1, 0.005}, {5, 0.005}, viewpoint, 0.01, 0.0035), 3,
                                        options, std::ref(rules));
    EXPECT_EQ(more.state.elements.size(), 1u);
    EXPECT_EQ(more.decisions.front().matched_element, surface.id());
  }
  // It keeps facing both ways as views from one side merge into it: the next view from the other side merges too.
  auto seen_from_below = joined.state;
  for (std::int64_t seq = 3; seq < 6; ++seq)
    seen_from_below = apply_observation(seen_from_below, view_from({1, 0.005}, {5, 0.005}, {3, -2}, 0.01, 0.0035), seq,
                                        options, std::ref(rules))
                          .state;
  EXPECT_FALSE(seen_from_below.elements.at(surface.number).facing_rad.has_value());
  EXPECT_TRUE(seen_from_below.elements.at(surface.number).both_ways);
  const auto from_above = apply_observation(seen_from_below, view_from({1, 0.005}, {5, 0.005}, {3, 2}, 0.01, 0.0035), 6,
                                            options, std::ref(rules));
  EXPECT_EQ(from_above.decisions.front().matched_element, surface.id());
  // Its extent was partly seen from the other side, so a surface 11 cm in front of it that lies over it is not
  // hidden by it and may be another one: a noisy view (σ 4 cm, within the gate) of one stays apart.
  const auto in_front = apply_observation(seen_from_below, view_from({2, -0.11}, {3.5, -0.11}, {3, -2}, 0.04, 0.0087),
                                          6, options, std::ref(rules));
  EXPECT_EQ(in_front.state.elements.size(), 2u);
  // 5 cm apart is more than thin_surface_m: two faces.
  const auto thick =
      apply_observation(state, view_from({0, 0.05}, {6, 0.05}, {3, 2}, 0.01, 0.0035), 2, options, std::ref(rules));
  EXPECT_EQ(thick.state.elements.size(), 2u);
}

// A posted segment has no side; the first view from a scan gives its element one (it is not a thin surface).
TEST(FacingTest, AnElementOfUnknownSideTakesTheSideOfTheFirstViewThatMerges) {
  WorldOptions options;
  JoiningRules rules;
  const auto posted = apply_observation(WorldState{}, view_from({0, 0}, {6, 0}, {3, -2}, 0.01, 0.0035, false), 1,
                                        options, std::ref(rules));
  ASSERT_EQ(posted.state.elements.size(), 1u);
  const Element& unknown = (*posted.state.elements.begin()).second;
  EXPECT_FALSE(unknown.facing_rad.has_value());
  EXPECT_FALSE(unknown.both_ways);
  const auto seen = apply_observation(posted.state, view_from({1, 0.005}, {5, 0.005}, {3, -2}, 0.01, 0.0035), 2,
                                      options, std::ref(rules));
  ASSERT_EQ(seen.state.elements.size(), 1u);
  const Element& known = seen.state.elements.at(unknown.number);
  ASSERT_TRUE(known.facing_rad.has_value());
  EXPECT_NEAR(std::sin(*known.facing_rad), -1.0, 1e-6);
  EXPECT_FALSE(known.both_ways);
}

}  // namespace
}  // namespace wm::world
