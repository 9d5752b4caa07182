// The plan commands through the service that runs them on its writer, with a real store and the shipped rules: each
// command that changes the plan leaves the rules' facts and the listed changes following the plan as committed, and
// each undo takes back exactly the step before it.
#include "server/service/plan_commands.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "server/service/service_errors.h"
#include "server/service/service_test_helpers.h"
#include "server/service/world_service.h"
#include "support/temp_dir.h"

namespace wm::service {
namespace {

// The distance from the origin of wall w's edge as the rules see it (edge/5 holds its line in Hesse normal form).
double rules_rho_of_wall(WorldService& world) {
  const auto result = world.query("edge(w, _, Rho, _, _)", 2);
  EXPECT_EQ(result.solutions.size(), 1u);
  if (result.solutions.empty()) return NAN;
  const auto& rho = result.solutions[0][0];
  return std::abs(rho.kind == rules::QueryValue::Kind::integer ? static_cast<double>(rho.integer) : rho.floating);
}

std::size_t facts_of(WorldService& world, const std::string& goal) {
  const auto result = world.query("aggregate_all(count, " + goal + ", N)", 1);
  EXPECT_EQ(result.solutions.size(), 1u);
  return result.solutions.empty() ? 0 : static_cast<std::size_t>(result.solutions[0][0].integer);
}

std::vector<world::Change> listed(WorldService& world) {
  std::shared_ptr<const world::WorldState> state;
  std::shared_ptr<const world::PlanReport> evidence;
  return world.changes(state, evidence);
}

struct Served {
  testing::TempDir dir;
  storage::Store store{{(dir.path() / "world.db").string(), false}};
  rules::Engine engine{rules::EngineOptions{WM_SOURCE_DIR "/rules/prolog"}};
  common::Diagnostics diagnostics;
  WorldService world{ServiceOptions{}, store, engine, diagnostics};
};

TEST(PlanCommandsTest, APlacementAndItsUndoMoveThePlanAndTheRulesSeeItWhereItIsEachTime) {
  Served s;
  EXPECT_THROW(s.world.place_floor_plan({}, "{}"), Conflict);  // no plan: nothing to place
  s.world.load_floor_plan(wall_plan());
  EXPECT_NEAR(rules_rho_of_wall(s.world), 2.0, 1e-9);
  EXPECT_THROW(s.world.undo_placement("test"), Conflict);  // placed as drawn: nothing to undo

  world::PlacementChange change;
  change.placement = {1.0, 0.0, 0.0, 1.0};
  change.rule = "placed";
  change.explanation = "moved by a metre";
  change.observer = "test";
  const auto placed = s.world.place_floor_plan(change, "{}");
  EXPECT_EQ(placed.decision.rule, "placed");
  EXPECT_DOUBLE_EQ(s.world.snapshot()->placement.x_m, 1.0);
  EXPECT_NEAR(rules_rho_of_wall(s.world), 3.0, 1e-9);  // the rules see the edge where the plan now is

  const auto undone = s.world.undo_placement("test");
  EXPECT_EQ(undone.decision.rule, "placement_undone");
  EXPECT_GT(undone.version, placed.version);
  EXPECT_DOUBLE_EQ(s.world.snapshot()->placement.x_m, 0.0);
  EXPECT_NEAR(rules_rho_of_wall(s.world), 2.0, 1e-9);
  EXPECT_THROW(s.world.undo_placement("test"), Conflict);
}

TEST(PlanCommandsTest, ANewWallRejectedAcceptedAndUndoneChangesThePlanTheFactsAndTheListEachTime) {
  Served s;
  auto plan = wall_plan();  // and a second wall, so that the plan's footprint takes in y = 3
  plan.objects.push_back(plan.objects.front());
  plan.objects.back().id = "v";
  plan.objects.back().polylines = {{{-1, 5}, {5, 5}}};
  s.world.load_floor_plan(plan);
  for (int views = 0; views < 3; ++views)  // a wall the plan does not have, seen often enough to be one
    s.world.post_primitives(one_line({0, 3}, {4, 3}), "{}", std::nullopt);
  auto changes = listed(s.world);
  const auto is_new_wall = [](const world::Change& c) { return c.kind == world::ChangeKind::new_wall; };
  ASSERT_EQ(std::count_if(changes.begin(), changes.end(), is_new_wall), 1);
  const auto id = std::find_if(changes.begin(), changes.end(), is_new_wall)->id;
  EXPECT_THROW(s.world.decide_change("c000000000000", true, "test"), NotFound);

  // Rejected: no longer listed, the plan as it was; the undo lists it again.
  const auto rejected = s.world.decide_change(id, false, "test");
  EXPECT_EQ(rejected.decision.rule, "change_rejected");
  EXPECT_EQ(listed(s.world).size(), changes.size() - 1);
  EXPECT_EQ(s.world.snapshot()->objects.size(), 2u);
  const auto relisted = s.world.undo_change("test");
  EXPECT_EQ(relisted.change_id, id);
  EXPECT_EQ(relisted.decision.rule, "change_undone");
  EXPECT_EQ(listed(s.world).size(), changes.size());

  // Accepted: drawn into the plan as an object of its own, its element gone, and the rules know both at once.
  EXPECT_EQ(facts_of(s.world, "object(_, _)"), 2u);
  EXPECT_EQ(facts_of(s.world, "element(_, _, _, _, _, _, _, _)"), 1u);
  const auto accepted = s.world.decide_change(id, true, "test");
  ASSERT_TRUE(accepted.added_object.has_value());
  EXPECT_EQ(accepted.decision.rule, "change_accepted");
  EXPECT_EQ(s.world.snapshot()->objects.size(), 3u);
  EXPECT_TRUE(s.world.snapshot()->elements.empty());
  EXPECT_EQ(facts_of(s.world, "object(_, _)"), 3u);
  EXPECT_EQ(facts_of(s.world, "element(_, _, _, _, _, _, _, _)"), 0u);
  changes = listed(s.world);
  EXPECT_EQ(std::count_if(changes.begin(), changes.end(), is_new_wall), 0);

  // Undone: the plan is back as it was before it, and so are the rules' objects; nothing is left to undo.
  s.world.undo_change("test");
  EXPECT_EQ(s.world.snapshot()->objects.size(), 2u);
  EXPECT_EQ(facts_of(s.world, "object(_, _)"), 2u);
  EXPECT_THROW(s.world.undo_change("test"), Conflict);
}

}  // namespace
}  // namespace wm::service
