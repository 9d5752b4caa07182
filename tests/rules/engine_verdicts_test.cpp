#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "rules/engine.h"
#include "tests/rules/rules_test_helpers.h"

namespace wm::rules {
namespace {

using testing::options_for;
using testing::read_text;
using testing::write_text;

// The shipped rules with the demo floor plan (w1 solid, 4 m; t1 not_deformable, two edges; d1 a door).
using VerdictsTest = testing::ShippedRulesTest;

// Evidence with 250 beams through the edge (and 40 through each stretch) unless the test says otherwise.
EdgeEvidenceFacts evidence(std::string object, std::string edge, double backed, double seen_through, double observed,
                           std::vector<std::pair<double, double>> stretches = {}, std::int64_t beams_through = 250) {
  EdgeEvidenceFacts f{std::move(object), std::move(edge), backed, seen_through, observed, {}, beams_through, 0};
  for (const auto& [s0, s1] : stretches) f.stretches.push_back({s0, s1, beams_through > 0 ? 40 : 0});
  return f;
}

TEST_F(VerdictsTest, SolidWallSeenThroughIsMissingOverItsWholeLength) {
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 0.0, 0.9, 0.95, {{0.0, 3.8}})}, true);
  const auto verdicts = engine_.plan_verdicts(std::nullopt, 100);
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].object_id, "w1");
  EXPECT_EQ(verdicts[0].edge_id, "w1_e0");
  EXPECT_EQ(verdicts[0].verdict, "missing");
  EXPECT_EQ(verdicts[0].rule, "wall_missing");
  EXPECT_DOUBLE_EQ(verdicts[0].s0_m, 0.0);
  EXPECT_DOUBLE_EQ(verdicts[0].s1_m, 4.0);  // the edge's length
  // The explanation says how much was seen through: 0.9 of 4 m.
  EXPECT_NE(verdicts[0].explanation.find("3.60 m"), std::string::npos) << verdicts[0].explanation;
}

TEST_F(VerdictsTest, BackedWallWithADoorCutInIsPartlyMissingOverTheStretch) {
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 0.7, 0.25, 0.95, {{1.5, 2.5}})}, true);
  const auto verdicts = engine_.plan_verdicts(std::nullopt, 100);
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].verdict, "partly_missing");
  EXPECT_EQ(verdicts[0].rule, "wall_partly_missing");
  EXPECT_DOUBLE_EQ(verdicts[0].s0_m, 1.5);
  EXPECT_DOUBLE_EQ(verdicts[0].s1_m, 2.5);
}

TEST_F(VerdictsTest, AStretchWhoseBeamsMostlyEndOnItIsNoVerdict) {
  // A thin wall seen from both sides with a poor pose: its cells freed, but most of its beams returned on it.
  auto thin = evidence("w1", "w1_e0", 0.7, 0.25, 0.95, {{1.5, 2.5}});
  thin.stretches[0].beams_ended = 41;  // 40 through: fewer passed than returned
  engine_.set_edge_evidence({thin}, true);
  EXPECT_TRUE(engine_.plan_verdicts(std::nullopt, 100).empty());
  // Both forms of the fact answer: with the returns, and without (rule files written before they were counted).
  const auto with_ended = engine_.query("edge_seen_through(w1, w1_e0, _, _, T, E)", 10);
  ASSERT_EQ(with_ended.solutions.size(), 1u);
  EXPECT_EQ(with_ended.solutions[0].at(0).integer, 40);
  EXPECT_EQ(with_ended.solutions[0].at(1).integer, 41);
  const auto through_only = engine_.query("edge_seen_through(w1, w1_e0, _, _, T)", 10);
  ASSERT_EQ(through_only.solutions.size(), 1u);
  EXPECT_EQ(through_only.solutions[0].at(0).integer, 40);
  thin.stretches[0].beams_ended = 40;  // as many passed as returned: the stretch is missing
  engine_.set_edge_evidence({thin}, true);
  ASSERT_EQ(engine_.plan_verdicts(std::nullopt, 100).size(), 1u);
  thin.stretches[0].beams_ended = -1;
  EXPECT_THROW(engine_.set_edge_evidence({thin}, true), std::invalid_argument);
}

TEST_F(VerdictsTest, WallBackedOrBarelySeenHasNoVerdict) {
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 0.9, 0.0, 0.95)}, true);
  EXPECT_TRUE(engine_.plan_verdicts(std::nullopt, 100).empty());
  // Seen through where seen, but only a fifth of it seen: a glimpse is no verdict.
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 0.0, 0.2, 0.2)}, true);
  EXPECT_TRUE(engine_.plan_verdicts(std::nullopt, 100).empty());
}

TEST_F(VerdictsTest, FreeCellsThatNoBeamCrossedAreNoVerdict) {
  // Beams running along a wall clear its cells without passing through it: no evidence that it has gone.
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 0.0, 0.9, 0.95, {{0.0, 3.8}}, 0)}, true);
  EXPECT_TRUE(engine_.plan_verdicts(std::nullopt, 100).empty());
  const auto beams = engine_.query("edge_beams(w1, w1_e0, T, E)", 10);
  ASSERT_EQ(beams.solutions.size(), 1u);
}

TEST_F(VerdictsTest, DoorWithoutSolidIsNeverMissing) {
  engine_.set_edge_evidence({evidence("d1", "d1_e0", 0.0, 1.0, 1.0, {{0.0, 0.9}})}, true);
  EXPECT_TRUE(engine_.plan_verdicts(std::nullopt, 100).empty());
}

TEST_F(VerdictsTest, TableWhoseEdgesAreAllSeenThroughIsGone) {
  engine_.set_edge_evidence(
      {evidence("t1", "t1_e0", 0.0, 0.9, 0.9, {{0.0, 0.8}}), evidence("t1", "t1_e1", 0.02, 0.8, 0.9, {{0.0, 0.6}})},
      true);
  const auto verdicts = engine_.plan_verdicts(std::nullopt, 100);
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].object_id, "t1");
  EXPECT_FALSE(verdicts[0].edge_id.has_value());
  EXPECT_EQ(verdicts[0].verdict, "gone");
  EXPECT_EQ(verdicts[0].rule, "object_gone");
  // One edge backed: the table is there.
  engine_.set_edge_evidence({evidence("t1", "t1_e1", 0.6, 0.1, 0.9)}, false);
  EXPECT_TRUE(engine_.plan_verdicts(std::nullopt, 100).empty());
}

TEST_F(VerdictsTest, ScopeLimitsTheEdgesAndObjectsAsked) {
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 0.0, 0.9, 0.95)}, true);
  EXPECT_TRUE(engine_.plan_verdicts(std::vector<EdgeKey>{{"t1", "t1_e0"}}, 100).empty());
  EXPECT_EQ(engine_.plan_verdicts(std::vector<EdgeKey>{{"w1", "w1_e0"}}, 100).size(), 1u);
}

TEST_F(VerdictsTest, ReplacingEvidenceDropsTheEdgesOldFactsAndReplaceAllDropsEveryEdge) {
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 0.0, 0.9, 0.95, {{0.0, 3.8}})}, true);
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 1.0, 0.0, 1.0)}, false);
  EXPECT_TRUE(engine_.plan_verdicts(std::nullopt, 100).empty());
  const auto stretches = engine_.query("edge_seen_through(w1, E, S0, S1, N)", 10);
  EXPECT_TRUE(stretches.solutions.empty());
  engine_.set_edge_evidence({}, true);
  EXPECT_TRUE(engine_.query("edge_evidence(O, E, B, S, Obs)", 10).solutions.empty());
}

TEST_F(VerdictsTest, BadEvidenceIsRefusedAndChangesNothing) {
  engine_.set_edge_evidence({evidence("w1", "w1_e0", 0.0, 0.9, 0.95)}, true);
  EXPECT_THROW(engine_.set_edge_evidence({evidence("w1", "w1_e0", std::nan(""), 0.9, 0.95)}, true),
               std::invalid_argument);
  EXPECT_THROW(engine_.set_edge_evidence({evidence("", "w1_e0", 0, 0, 0)}, false), std::invalid_argument);
  EXPECT_THROW(engine_.set_edge_evidence(
                   {evidence("w1", "w1_e0", 0, 0, 0, {{0.0, std::numeric_limits<double>::infinity()}})}, false),
               std::invalid_argument);
  EXPECT_EQ(engine_.plan_verdicts(std::nullopt, 100).size(), 1u);
}

TEST(VerdictsRulesTest, GlassExampleKeepsAGlassWallFromBeingCalledMissing) {
  testing::TempDir dir;
  testing::copy_shipped_rules(dir);
  write_text(dir / "glass.pl", read_text(std::filesystem::path(WM_SOURCE_DIR) / "rules/examples/glass.pl"));
  Engine engine(options_for(dir));
  engine.set_floor_plan({{"g1", "wall", {"solid", "glass"}, {{"g1_e0", 2.0, 0.0, 4.0}}},
                         {"w1", "wall", {"solid"}, {{"w1_e0", 3.0, 0.0, 4.0}}}});
  engine.set_edge_evidence(
      {evidence("g1", "g1_e0", 0.0, 1.0, 1.0, {{0.0, 4.0}}), evidence("w1", "w1_e0", 0.0, 1.0, 1.0, {{0.0, 4.0}})},
      true);
  const auto verdicts = engine.plan_verdicts(std::nullopt, 100);
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].object_id, "w1");  // the glass wall has none
}

TEST(VerdictsRulesTest, UserRuleThatLoopsGivesNoVerdictsAndAnError) {
  testing::TempDir dir;
  testing::copy_shipped_rules(dir);
  write_text(dir / "zz_loop.pl",
             "verdict_override(O, E, V, R, X) :- spin(O, E, V, R, X).\n"
             "spin(O, E, V, R, X) :- spin(O, E, V, R, X).\n");
  Engine engine(options_for(dir));
  engine.set_floor_plan(testing::demo_floor_plan());
  engine.set_edge_evidence({evidence("w1", "w1_e0", 0.0, 0.9, 0.95)}, true);
  EXPECT_TRUE(engine.plan_verdicts(std::nullopt, 100).empty());
  EXPECT_NE(engine.status().last_error.find("verdicts"), std::string::npos) << engine.status().last_error;
}

}  // namespace
}  // namespace wm::rules
