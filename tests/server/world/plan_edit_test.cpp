// Changes accepted into the drawing: edges taken out or cut, objects removed or redrawn where they stand, new
// walls drawn; and the state after the edit keeps what was learnt of the objects the edit did not touch.
#include "server/world/plan_edit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace wm::world {
namespace {

apriori::PlanObject object(std::string id, std::vector<std::vector<Eigen::Vector2d>> polylines,
                           std::vector<Eigen::Vector2d> polygon = {}, fusion::Pose2D pose = {0, 0, 0}) {
  apriori::PlanObject o;
  o.id = std::move(id);
  o.kind = polygon.empty() ? "wall" : "table";
  o.attributes = {polygon.empty() ? "solid" : "not_deformable"};
  o.polylines = std::move(polylines);
  o.polygon = std::move(polygon);
  o.pose = pose;
  return o;
}

// "l": an L of two walls (0,0)-(10,0)-(10,3); "t": a 1 × 0.5 m table at (5, 5); "w": a wall (0,8)-(4,8).
// Placed in the world by a similarity (shifted by (100, 50), turned 90°) unless `as_drawn`.
WorldState state(bool as_drawn = false) {
  apriori::FloorPlan plan;
  plan.name = "p";
  plan.objects = {object("l", {{{0, 0}, {10, 0}, {10, 3}}}),
                  object("t", {}, {{-0.5, -0.25}, {0.5, -0.25}, {0.5, 0.25}, {-0.5, 0.25}}, {5, 5, 0}),
                  object("w", {{{0, 8}, {4, 8}}})};
  WorldState s;
  s.version = 3;
  s.plan_name = plan.name;
  if (!as_drawn) s.placement = {100, 50, std::numbers::pi / 2, 1.0};
  s.objects = ObjectTable(make_objects(plan, WorldOptions{}, 3, s.placement));
  return s;
}

Change change_of(ChangeKind kind, std::string object_id, std::optional<std::size_t> edge = std::nullopt) {
  Change c;
  c.kind = kind;
  c.object_id = std::move(object_id);
  c.edge = edge;
  return c;
}

const apriori::PlanObject* find(const apriori::FloorPlan& plan, const std::string& id) {
  for (const auto& o : plan.objects)
    if (o.id == id) return &o;
  return nullptr;
}

void expect_near(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  EXPECT_NEAR(a.x(), b.x(), 1e-9);
  EXPECT_NEAR(a.y(), b.y(), 1e-9);
}

TEST(PlanEditTest, MissingEdgeIsTakenOutOfItsPolyline) {
  const auto plan = plan_with_change(state(), change_of(ChangeKind::wall_missing, "l", 0));
  const auto* l = find(plan, "l");
  ASSERT_NE(l, nullptr);
  ASSERT_EQ(l->polylines.size(), 1u);
  ASSERT_EQ(l->polylines[0].size(), 2u);
  expect_near(l->polylines[0][0], {10, 0});
  expect_near(l->polylines[0][1], {10, 3});
  // A wall of one edge goes with it.
  EXPECT_EQ(find(plan_with_change(state(), change_of(ChangeKind::wall_missing, "w", 0)), "w"), nullptr);
}

TEST(PlanEditTest, PartlyMissingEdgeIsCutOverTheStretchInTheDrawingFrame) {
  const auto s = state();
  // The stretch from x = 3 to 5 of the drawing's first wall, given in the world (through the placement).
  auto c = change_of(ChangeKind::wall_partly_missing, "l", 0);
  c.p0 = s.placement.transform_point({5, 0});  // either order
  c.p1 = s.placement.transform_point({3, 0});
  const auto plan = plan_with_change(s, c);
  const auto* l = find(plan, "l");
  ASSERT_NE(l, nullptr);
  ASSERT_EQ(l->polylines.size(), 2u);
  ASSERT_EQ(l->polylines[0].size(), 2u);
  expect_near(l->polylines[0][0], {0, 0});
  expect_near(l->polylines[0][1], {3, 0});
  ASSERT_EQ(l->polylines[1].size(), 3u);
  expect_near(l->polylines[1][0], {5, 0});
  expect_near(l->polylines[1][2], {10, 3});
  // The other objects are as drawn.
  EXPECT_EQ(find(plan, "w")->polylines, find(current_plan(s), "w")->polylines);
}

TEST(PlanEditTest, MissingSideOfAnOutlineOpensIt) {
  const auto plan = plan_with_change(state(true), change_of(ChangeKind::wall_missing, "t", 0));
  const auto* t = find(plan, "t");
  ASSERT_NE(t, nullptr);
  EXPECT_TRUE(t->polygon.empty());
  ASSERT_EQ(t->polylines.size(), 1u);
  ASSERT_EQ(t->polylines[0].size(), 4u);  // from the side's end around to its start
  expect_near(t->polylines[0].front(), {0.5, -0.25});
  expect_near(t->polylines[0].back(), {-0.5, -0.25});
  EXPECT_EQ(t->edges().size(), 3u);
}

TEST(PlanEditTest, GoneObjectIsRemovedAndMovedObjectIsDrawnWhereItStands) {
  auto s = state();
  EXPECT_EQ(find(plan_with_change(s, change_of(ChangeKind::object_gone, "t")), "t"), nullptr);
  auto table = s.objects[1];
  const auto drawn_world = table.body.pose();
  table.body = fusion::RigidObject({drawn_world.x_m + 0.3, drawn_world.y_m - 0.2, drawn_world.theta_rad + 0.1},
                                   table.body.pose_cov(), table.body.edges());
  table.adjustments = 4;
  s.objects.put(1, table);
  const auto plan = plan_with_change(s, change_of(ChangeKind::object_moved, "t"));
  const auto& pose = find(plan, "t")->pose;
  // The placement turns by 90°: a world move of (+0.3, −0.2) is (−0.2, −0.3) in the drawing.
  EXPECT_NEAR(pose.x_m, 5 - 0.2, 1e-9);
  EXPECT_NEAR(pose.y_m, 5 - 0.3, 1e-9);
  EXPECT_NEAR(pose.theta_rad, 0.1, 1e-9);
}

TEST(PlanEditTest, NewWallIsDrawnAlongTheElementWithAUniqueId) {
  auto s = state();
  Element e;
  e.number = 7;
  e.segment = fusion::LineSegment::from_points(s.placement.transform_point({1, 1}), s.placement.transform_point({1, 4}),
                                               Eigen::Matrix2d::Identity() * 1e-4);
  s.elements.put(e);
  Change c;
  c.kind = ChangeKind::new_wall;
  c.element_id = "e7";
  std::string added;
  const auto plan = plan_with_change(s, c, &added);
  EXPECT_EQ(added, "e7-wall");
  const auto* wall = find(plan, "e7-wall");
  ASSERT_NE(wall, nullptr);
  EXPECT_EQ(wall->attributes, std::vector<std::string>{"solid"});
  ASSERT_EQ(wall->polylines.size(), 1u);
  const auto& line = wall->polylines[0];
  EXPECT_NEAR(std::min(line[0].y(), line[1].y()), 1.0, 1e-9);
  EXPECT_NEAR(std::max(line[0].y(), line[1].y()), 4.0, 1e-9);
  EXPECT_NEAR(line[0].x(), 1.0, 1e-9);
  c.element_id = "e8";
  EXPECT_THROW(plan_with_change(s, c), std::invalid_argument);
  EXPECT_THROW(plan_with_change(s, change_of(ChangeKind::object_gone, "nope")), std::invalid_argument);
  EXPECT_THROW(plan_with_change(s, change_of(ChangeKind::wall_missing, "l", 5)), std::invalid_argument);
}

TEST(PlanEditTest, EditKeepsWhatWasLearntOfUntouchedObjectsAndLogsOneDecision) {
  auto s = state();
  auto table = s.objects[1];
  table.adjustments = 2;
  table.confirmations = 9;
  table.body = fusion::RigidObject({1, 2, 0.5}, table.body.pose_cov(), table.body.edges());
  s.objects.put(1, table);
  auto wall = s.objects[0];
  wall.confirmations = 5;
  s.objects.put(0, wall);
  Element e;
  e.number = 3;
  e.segment = fusion::LineSegment::from_points({0, 0}, {1, 0}, Eigen::Matrix2d::Identity() * 1e-4);
  s.elements.put(e);
  s.last_observation_seq = 40;
  s.last_decision_seq = 90;
  const auto plan = plan_with_change(s, change_of(ChangeKind::wall_missing, "l", 1));
  const auto result = apply_plan_edit(s, plan, WorldOptions{}, {3}, 41, rules::Action::accept, "change_accepted",
                                      "accepted", "alice", "l");
  const auto& after = result.state;
  EXPECT_EQ(after.version, 4);
  EXPECT_EQ(after.last_observation_seq, 41);
  ASSERT_EQ(after.objects.size(), 3u);
  // The table's drawing did not change: its learnt pose stays.
  EXPECT_EQ(after.objects[1].adjustments, 2);
  EXPECT_NEAR(after.objects[1].body.pose().x_m, 1.0, 1e-12);
  // The L lost an edge: rebuilt from the new drawing, its confirmations kept.
  EXPECT_EQ(after.objects[0].body.edges().size(), 1u);
  EXPECT_EQ(after.objects[0].confirmations, 5);
  EXPECT_FALSE(after.elements.contains(3));
  EXPECT_EQ(result.removed_elements, std::set<std::int64_t>{3});
  ASSERT_EQ(result.decisions.size(), 1u);
  EXPECT_EQ(result.decisions[0].seq, 91);
  EXPECT_EQ(result.decisions[0].action, rules::Action::accept);
  EXPECT_EQ(result.decisions[0].object, "l");
  EXPECT_EQ(result.decisions[0].observer, "alice");
}

}  // namespace
}  // namespace wm::world
