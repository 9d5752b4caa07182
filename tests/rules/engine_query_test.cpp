#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "rules/engine.h"
#include "tests/rules/rules_test_helpers.h"

namespace wm::rules {
namespace {

using testing::demo_floor_plan;
using testing::matched;
using testing::read_text;
using testing::unmatched;
using testing::write_text;

std::filesystem::path examples_dir() { return std::filesystem::path(WM_RULES_PROLOG_DIR) / ".." / "examples"; }

class KnowledgeBaseTest : public testing::ShippedRulesTest {
 protected:
  KnowledgeBaseTest() {
    engine_.set_elements(
        {{"e1", "scan", "robot-1", 1.0, 0.5, 2.0, 1, 100.0}, {"e2", "client", "robot-2", 3.0, 0.1, 0.7, 4, 200.0}});
  }

  // The single value of variable `name` in the only solution of `goal`.
  QueryValue only(const std::string& goal, const std::string& name) {
    const auto result = engine_.query(goal, 10);
    EXPECT_EQ(result.solutions.size(), 1u) << goal;
    const auto at = std::find(result.variables.begin(), result.variables.end(), name);
    EXPECT_NE(at, result.variables.end()) << goal;
    if (result.solutions.size() != 1 || at == result.variables.end()) return {};
    return result.solutions[0][static_cast<std::size_t>(at - result.variables.begin())];
  }
};

TEST_F(KnowledgeBaseTest, QueriesSeeObjectsAttributesEdgesAndElements) {
  const auto solid = engine_.query("attribute(O, solid)", 10);
  ASSERT_EQ(solid.variables, std::vector<std::string>{"O"});
  ASSERT_EQ(solid.solutions.size(), 1u);
  EXPECT_EQ(solid.solutions[0][0].kind, QueryValue::Kind::atom);
  EXPECT_EQ(solid.solutions[0][0].text, "w1");

  EXPECT_EQ(only("aggregate_all(count, edge(t1, _, _, _, _), N)", "N").integer, 2);
  const auto rho = only("edge(t1, t1_e1, Rho, _, _)", "Rho");
  EXPECT_EQ(rho.kind, QueryValue::Kind::floating);
  EXPECT_DOUBLE_EQ(rho.floating, 1.5);
  EXPECT_EQ(only("element(E, scan, _, _, _, _, _, _)", "E").text, "e1");
  EXPECT_EQ(only("element(e2, _, _, _, _, _, Support, _)", "Support").integer, 4);

  const auto list = only("findall(O, object(O, _), L)", "L");
  ASSERT_EQ(list.kind, QueryValue::Kind::list);
  ASSERT_EQ(list.items.size(), 3u);
  EXPECT_EQ(list.items[2].text, "d1");
  EXPECT_EQ(only("X = point(1, 2)", "X").text, "point(1,2)");
  EXPECT_EQ(only("format(string(S), \"~w-~w\", [a, b])", "S").text, "a-b");
}

TEST_F(KnowledgeBaseTest, QueriesCanAskTheActiveRulesWhatIf) {
  const auto action = only("decide(observation(r, 2.0, 0.0, 3.5), element(e, w1, 0.1), A, R, _)", "A");
  EXPECT_EQ(action.text, "delete");
  EXPECT_EQ(only("decide(observation(r, 2.0, 0.0, 3.5), none, _, R, _)", "R").text, "unmatched_added");
}

TEST_F(KnowledgeBaseTest, DecisionFactsKeepOnlyTheNewest) {
  std::vector<DecisionFacts> batch;
  for (int i = 1; i <= 7; ++i)
    batch.push_back({i, "add", "unmatched_added", "e" + std::to_string(i), std::nullopt, "r", 1.0 * i});
  engine_.add_decisions(batch, 5);
  engine_.add_decisions({{8, "delete", "solid_confirmed", std::string("w1/0"), std::string("w1"), "r", 8.0}}, 5);
  const auto seqs = engine_.query("decision(S, _, _, _, _, _, _)", 100);
  ASSERT_EQ(seqs.solutions.size(), 5u);
  EXPECT_EQ(seqs.solutions.front()[0].integer, 4);
  EXPECT_EQ(seqs.solutions.back()[0].integer, 8);
  EXPECT_EQ(only("decision(8, _, _, _, O, _, _)", "O").text, "w1");
  EXPECT_EQ(only("decision(7, _, _, _, O, _, _)", "O").text, "none");
}

TEST_F(KnowledgeBaseTest, QueryAnswersAreCappedAndSayso) {
  const auto result = engine_.query("between(1, 1000, X)", 10);
  EXPECT_EQ(result.solutions.size(), 10u);
  EXPECT_TRUE(result.truncated);
  EXPECT_EQ(result.solutions[9][0].integer, 10);
  EXPECT_FALSE(engine_.query("between(1, 10, X)", 10).truncated);
  EXPECT_TRUE(engine_.query("attribute(nobody, _)", 10).solutions.empty());
}

TEST_F(KnowledgeBaseTest, DangerousGoalsAreRefusedAndChangeNothing) {
  const auto marker = dir_ / "written-by-a-query";
  const std::vector<std::string> dangerous = {
      "shell('touch " + marker.string() + "')",
      "open('" + marker.string() + "', write, S)",
      "delete_file('" + (dir_ / "world_model.pl").string() + "')",
      "assertz(object(evil, wall))",
      "asserta(attribute(w1, glass))",
      "retract(attribute(w1, solid))",
      "retractall(object(_, _))",
      "wm_kb:assertz(object(evil, wall))",
      "G = assertz(object(evil, wall)), call(G)",
      "call(assertz, object(evil, wall))",
      "abolish(object/2)",
      "consult('/etc/passwd')",
      "halt",
      "setenv('PATH', '')",
      "thread_create(true, _, [])",
      "nb_setval(k, v)",
      "set_prolog_flag(unknown, fail)",
      "read_term(user_input, _, [])",
  };
  for (const auto& goal : dangerous) {
    try {
      engine_.query(goal, 10);
      ADD_FAILURE() << "not refused: " << goal;
    } catch (const QueryError& e) {
      EXPECT_EQ(e.reason(), QueryError::Reason::unsafe) << goal << ": " << e.what();
      EXPECT_FALSE(std::string(e.what()).empty());
    }
  }
  EXPECT_FALSE(std::filesystem::exists(marker));
  EXPECT_TRUE(std::filesystem::exists(dir_ / "world_model.pl"));
  EXPECT_EQ(engine_.query("object(O, _)", 10).solutions.size(), 3u);
  EXPECT_EQ(only("attribute(w1, A)", "A").text, "solid");
}

TEST_F(KnowledgeBaseTest, BadOrEndlessQueriesFailClearly) {
  try {
    engine_.query("attribute(O,", 10);
    ADD_FAILURE() << "syntax error accepted";
  } catch (const QueryError& e) {
    EXPECT_EQ(e.reason(), QueryError::Reason::syntax) << e.what();
  }
  for (const std::string goal : {"repeat, fail", "length(L, N), N > 100000000"}) {
    try {
      engine_.query(goal, 10);
      ADD_FAILURE() << "no limit hit: " << goal;
    } catch (const QueryError& e) {
      EXPECT_EQ(e.reason(), QueryError::Reason::limit) << goal << ": " << e.what();
    }
  }
  try {
    engine_.query("atom_length(X, _)", 10);
    ADD_FAILURE() << "error not reported";
  } catch (const QueryError& e) {
    EXPECT_EQ(e.reason(), QueryError::Reason::failed) << e.what();
  }
  EXPECT_EQ(engine_.decide(matched("w1_e0", "w1")).rule, "solid_confirmed") << "the engine still works";
}

TEST_F(KnowledgeBaseTest, ExamplesExtendTheShippedRulesInAnyFileOrder) {
  // glass.pl sorts before world_model.pl, movable.pl after it: both must work.
  for (const auto* name : {"glass.pl", "movable.pl", "prune_unconfirmed.pl"})
    write_text(dir_ / name, read_text(examples_dir() / name));
  engine_.reload();
  auto plan = demo_floor_plan();
  plan.push_back({"g1", "wall", {"solid", "glass"}, {{"g1_e0", 4.0, 0.0, 2.0}}});
  plan[2].attributes = {"movable"};
  engine_.set_floor_plan(plan);

  auto laser = matched("g1_e0", "g1");
  laser.sensor = "laser";
  EXPECT_EQ(engine_.decide(laser).rule, "glass_ignored");
  EXPECT_EQ(engine_.decide(laser).action, "ignore");
  auto sonar = laser;
  sonar.sensor = "sonar";
  EXPECT_EQ(engine_.decide(sonar).rule, "solid_confirmed");
  const auto door = engine_.decide(matched("d1_e0", "d1"));
  EXPECT_EQ(door.action, "merge");
  EXPECT_EQ(door.rule, "movable_merged");

  engine_.set_elements({{"e1", "scan", "r", 1.0, 0.5, 2.0, 1, 1.0}, {"e2", "scan", "r", 1.0, 0.5, 2.0, 3, 1.0}});
  const auto orders = engine_.prune_orders(100);
  ASSERT_EQ(orders.size(), 1u);
  EXPECT_EQ(orders[0].element_id, "e1");
  EXPECT_EQ(orders[0].rule, "unconfirmed_pruned");
  EXPECT_NE(orders[0].explanation.find("e1"), std::string::npos);
}

TEST_F(KnowledgeBaseTest, GridFactsReachTheShippedPruneRuleAndGoWhenTheElementChanges) {
  // e1 (scan) and e2 (client) are both seen through by the grid; the shipped rule removes only e1.
  engine_.set_element_grid({{"e1", 0.0, 0.9}, {"e2", 0.0, 1.0}});
  EXPECT_DOUBLE_EQ(only("element_grid(e1, _, C)", "C").floating, 0.9);
  auto orders = engine_.prune_orders(100);
  ASSERT_EQ(orders.size(), 1u);
  EXPECT_EQ(orders[0].element_id, "e1");
  EXPECT_EQ(orders[0].rule, "grid_unbacked");
  EXPECT_NE(orders[0].explanation.find("90 %"), std::string::npos) << orders[0].explanation;
  // A second check replaces the fact; a change of the element drops it, until the next check.
  engine_.set_element_grid({{"e1", 0.5, 0.5}});
  EXPECT_EQ(engine_.query("element_grid(e1, B, _)", 10).solutions.size(), 1u);
  EXPECT_DOUBLE_EQ(only("element_grid(e1, B, _)", "B").floating, 0.5);
  EXPECT_TRUE(engine_.prune_orders(100).empty());
  engine_.set_element_grid({{"e1", 0.0, 1.0}});
  engine_.update_elements({{"e1", "scan", "robot-1", 1.0, 0.5, 2.5, 2, 300.0}}, {});
  EXPECT_TRUE(engine_.query("element_grid(e1, _, _)", 10).solutions.empty());
  EXPECT_TRUE(engine_.prune_orders(100).empty());
  engine_.set_element_grid({{"e1", 0.0, 1.0}});
  engine_.update_elements({}, {"e1"});
  EXPECT_TRUE(engine_.query("element_grid(e1, _, _)", 10).solutions.empty());
  EXPECT_THROW(engine_.set_element_grid({{"e1", std::nan(""), 0.0}}), std::invalid_argument);
  EXPECT_THROW(engine_.set_element_grid({{"", 0.0, 0.0}}), std::invalid_argument);
}

TEST_F(KnowledgeBaseTest, PruneWithoutRulesIsEmptyAndALoopingPruneIsContained) {
  EXPECT_TRUE(engine_.prune_orders(100).empty());
  write_text(dir_ / "spin.pl", "prune(E, spin, \"x\") :- spin(E).\nspin(E) :- spin(E).\n");
  engine_.reload();
  EXPECT_TRUE(engine_.prune_orders(100).empty());
  EXPECT_NE(engine_.status().last_error.find("limit"), std::string::npos) << engine_.status().last_error;
}

TEST_F(KnowledgeBaseTest, BatchDecisionsEqualSingleDecisions) {
  std::vector<DecisionQuery> queries{matched("w1_e0", "w1"), matched("e5", std::nullopt), matched("t1_e0", "t1"),
                                     unmatched()};
  const auto batch = engine_.decide_batch(queries);
  ASSERT_EQ(batch.size(), queries.size());
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const auto single = engine_.decide(queries[i]);
    EXPECT_EQ(batch[i].action, single.action) << i;
    EXPECT_EQ(batch[i].rule, single.rule) << i;
    EXPECT_EQ(batch[i].explanation, single.explanation) << i;
  }
}

TEST_F(KnowledgeBaseTest, DryRunAnswersWithTheCandidateAndLeavesTheActiveRules) {
  const std::string shipped = read_text(dir_ / "world_model.pl");
  // The candidate merges what the shipped rules delete on solid walls.
  std::string candidate = shipped;
  const std::string from = "element(Element, Object, D2), delete, solid_confirmed,";
  const auto at = candidate.find(from);
  ASSERT_NE(at, std::string::npos);
  candidate.replace(at, from.size(), "element(Element, Object, D2), merge, solid_merged,");
  const auto answers = engine_.dry_run({"world_model.pl", candidate}, {matched("w1_e0", "w1"), unmatched()});
  ASSERT_EQ(answers.size(), 2u);
  EXPECT_EQ(answers[0].action, "merge");
  EXPECT_EQ(answers[0].rule, "solid_merged");
  EXPECT_EQ(answers[1].rule, "unmatched_added");
  EXPECT_EQ(engine_.decide(matched("w1_e0", "w1")).rule, "solid_confirmed") << "the active rules must not change";
  EXPECT_EQ(engine_.status().generation, 1);

  // A candidate with an error is rejected with its location, and nothing changes either.
  try {
    engine_.dry_run({"extra.pl", "override(_, _, delete, broken, \"x\") :- \n  foo(.\n"}, {unmatched()});
    ADD_FAILURE() << "broken candidate accepted";
  } catch (const RuleError& e) {
    EXPECT_NE(std::string(e.what()).find("extra.pl:"), std::string::npos) << e.what();
  }
  EXPECT_EQ(engine_.decide(unmatched()).rule, "unmatched_added");
  EXPECT_THROW(engine_.dry_run({"../evil.pl", "x."}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace wm::rules
