// The change list on its own: a new wall is a change of the building only where the plan draws it; what robots map
// far beyond the plan stays in the map but is not listed, and without a plan every element qualifies.
#include "server/world/changes.h"

#include <gtest/gtest.h>

#include "server/world/update.h"

namespace wm::world {
namespace {

// A 10 × 8 m room drawn as four solid walls.
ObjectTable room_plan() {
  apriori::FloorPlan plan;
  plan.name = "room";
  apriori::PlanObject room;
  room.id = "room";
  room.kind = "wall";
  room.attributes = {"solid"};
  room.polylines = {{{0, 0}, {10, 0}, {10, 8}, {0, 8}, {0, 0}}};
  plan.objects = {room};
  return ObjectTable(make_objects(plan, WorldOptions{}, 1));
}

// `state` with an element added from (a, b), decided "add".
WorldState with_element(const WorldState& state, Eigen::Vector2d a, Eigen::Vector2d b, std::int64_t seq) {
  Observation observation;
  observation.observer = "robot-1";
  auto segment = fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
  segment.line.cov = midpoint_line_cov(segment, 0.01, 0.01);
  observation.segments.push_back({segment});
  return apply_observation(state, observation, seq, WorldOptions{},
                           [](const rules::DecisionQuery&) {
                             return rules::Decision{"add", "r", "why", false};
                           })
      .state;
}

std::vector<std::string> new_walls(const WorldState& state, const ChangeOptions& options) {
  std::vector<std::string> ids;
  for (const auto& change : list_changes(state, nullptr, options))
    if (change.kind == ChangeKind::new_wall) ids.push_back(change.element_id);
  return ids;
}

TEST(ChangesTest, ANewWallIsListedOnlyWhereThePlanDrawsTheBuilding) {
  WorldState state;
  state.objects = room_plan();
  state = with_element(state, {3, 4}, {7, 4}, 1);      // a partition in the room: e1
  state = with_element(state, {14, -1}, {14, 3}, 2);   // 4 m outside a wall, within the 10 m margin: e2
  state = with_element(state, {100, 0}, {104, 0}, 3);  // a log replayed 100 m away: e3
  state = with_element(state, {9, 20}, {13, -20}, 4);  // crosses the room with both ends far outside: e4
  ChangeOptions options;
  options.min_new_wall_support = 1;
  EXPECT_EQ(new_walls(state, options), (std::vector<std::string>{"e1", "e2"}));
  options.plan_margin_m = -1;  // no limit
  EXPECT_EQ(new_walls(state, options).size(), 4u);
  options.plan_margin_m = 2;
  EXPECT_EQ(new_walls(state, options), (std::vector<std::string>{"e1"}));
}

TEST(ChangesTest, WithoutAPlanEveryElementQualifies) {
  WorldState state;
  state = with_element(state, {3, 4}, {7, 4}, 1);
  state = with_element(state, {100, 0}, {104, 0}, 2);
  ChangeOptions options;
  options.min_new_wall_support = 1;
  EXPECT_EQ(new_walls(state, options).size(), 2u);
}

}  // namespace
}  // namespace wm::world
