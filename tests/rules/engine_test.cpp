#include "rules/engine.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <regex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "tests/rules/rules_test_helpers.h"

namespace wm::rules {
namespace {

using testing::copy_shipped_rules;
using testing::demo_floor_plan;
using testing::matched;
using testing::options_for;
using testing::TempDir;
using testing::unmatched;
using testing::write_text;

// The shipped rules with the demo floor plan.
using WorldModelRulesTest = testing::ShippedRulesTest;

TEST_F(WorldModelRulesTest, MatchOnSolidObjectIsDeletedBySolidConfirmed) {
  const Decision decision = engine_.decide(matched("e7", "w1"));
  EXPECT_EQ(decision.action, "delete");
  EXPECT_EQ(decision.rule, "solid_confirmed");
  EXPECT_FALSE(decision.fallback);
}

TEST_F(WorldModelRulesTest, MatchOnElementNotInPlanIsMergedByUnknownElementMerged) {
  const Decision decision = engine_.decide(matched("e8", std::nullopt));
  EXPECT_EQ(decision.action, "merge");
  EXPECT_EQ(decision.rule, "unknown_element_merged");
  EXPECT_FALSE(decision.fallback);
}

TEST_F(WorldModelRulesTest, MatchOnNotDeformableObjectIsRigidAdjusted) {
  const Decision decision = engine_.decide(matched("t1_e0", "t1"));
  EXPECT_EQ(decision.action, "rigid_adjust");
  EXPECT_EQ(decision.rule, "not_deformable_rigid");
  EXPECT_FALSE(decision.fallback);
}

TEST_F(WorldModelRulesTest, UnmatchedObservationIsAddedByUnmatchedAdded) {
  const Decision decision = engine_.decide(unmatched());
  EXPECT_EQ(decision.action, "add");
  EXPECT_EQ(decision.rule, "unmatched_added");
  EXPECT_FALSE(decision.fallback);
}

TEST_F(WorldModelRulesTest, MatchOnPlainAprioriObjectIsDeletedByAprioriConfirmed) {
  const Decision decision = engine_.decide(matched("d1_e0", "d1"));
  EXPECT_EQ(decision.action, "delete");
  EXPECT_EQ(decision.rule, "apriori_confirmed");
  EXPECT_FALSE(decision.fallback);
}

TEST_F(WorldModelRulesTest, ExplanationMentionsElementObjectAndDistance) {
  const Decision decision = engine_.decide(matched("e7", "w1", 0.25));
  EXPECT_NE(decision.explanation.find("e7"), std::string::npos) << decision.explanation;
  EXPECT_NE(decision.explanation.find("w1"), std::string::npos) << decision.explanation;
  EXPECT_NE(decision.explanation.find("0.2500"), std::string::npos) << decision.explanation;
  EXPECT_NE(decision.explanation.find("lidar"), std::string::npos) << decision.explanation;
}

TEST_F(WorldModelRulesTest, UnmatchedExplanationGivesTheLineInSiUnits) {
  const Decision decision = engine_.decide(unmatched("sonar"));
  EXPECT_NE(decision.explanation.find("sonar"), std::string::npos) << decision.explanation;
  EXPECT_NE(decision.explanation.find("rho = 1.2500 m"), std::string::npos) << decision.explanation;
  EXPECT_NE(decision.explanation.find("phi = -0.5000 rad"), std::string::npos) << decision.explanation;
}

TEST_F(WorldModelRulesTest, IdsWithQuotesAndNonAsciiCharactersRoundTrip) {
  engine_.set_floor_plan({{"Wand 'Süd'", "wall", {"solid"}, {}}});
  const Decision decision = engine_.decide(matched("élément 1", "Wand 'Süd'"));
  EXPECT_EQ(decision.rule, "solid_confirmed");
  EXPECT_NE(decision.explanation.find("Wand 'Süd'"), std::string::npos) << decision.explanation;
  EXPECT_NE(decision.explanation.find("élément 1"), std::string::npos) << decision.explanation;
}

TEST_F(WorldModelRulesTest, SetFloorPlanReplacesOldObjects) {
  engine_.set_floor_plan({{"d2", "door", {}, {}}});

  const Decision old_wall = engine_.decide(matched("e7", "w1"));
  EXPECT_TRUE(old_wall.fallback) << "w1 must be gone, got rule " << old_wall.rule;
  EXPECT_EQ(old_wall.action, "add");
  EXPECT_EQ(old_wall.rule, "fallback");
  EXPECT_EQ(engine_.decide(matched("e9", "d2")).rule, "apriori_confirmed");
}

TEST_F(WorldModelRulesTest, EmptyFloorPlanRemovesEveryObject) {
  engine_.set_floor_plan({});
  EXPECT_TRUE(engine_.decide(matched("d1_e0", "d1")).fallback);
  EXPECT_EQ(engine_.decide(unmatched()).rule, "unmatched_added");
}

TEST_F(WorldModelRulesTest, InvalidFloorPlanIsRejectedAndKeepsTheOldFacts) {
  EXPECT_THROW(engine_.set_floor_plan({{"a", "wall", {}, {}}, {"a", "wall", {}, {}}}), std::invalid_argument);
  EXPECT_THROW(engine_.set_floor_plan({{"none", "wall", {}, {}}}), std::invalid_argument);
  EXPECT_THROW(engine_.set_floor_plan({{"", "wall", {}, {}}}), std::invalid_argument);
  EXPECT_THROW(engine_.set_floor_plan({{"b", "wall", {}, {{"e", std::nan(""), 0.0, 1.0}}}}), std::invalid_argument);
  EXPECT_EQ(engine_.decide(matched("e7", "w1")).rule, "solid_confirmed");
}

TEST_F(WorldModelRulesTest, InvalidQueryIsRejected) {
  auto query = matched("e7", "w1");
  query.rho_m = std::numeric_limits<double>::infinity();
  EXPECT_THROW(engine_.decide(query), std::invalid_argument);
  query = matched("e7", "w1", -1.0);
  EXPECT_THROW(engine_.decide(query), std::invalid_argument);
  query = unmatched();
  query.object_id = "w1";
  EXPECT_THROW(engine_.decide(query), std::invalid_argument);
  EXPECT_THROW(engine_.decide(matched("e7", "none")), std::invalid_argument);
}

TEST_F(WorldModelRulesTest, StatusListsTheLoadedFileWithItsSha256) {
  const RulesStatus status = engine_.status();
  ASSERT_EQ(status.files.size(), 1u);
  EXPECT_EQ(status.files[0].path, (dir_ / "world_model.pl").string());
  EXPECT_TRUE(std::regex_match(status.files[0].sha256_or_checksum, std::regex("[0-9a-f]{64}")))
      << status.files[0].sha256_or_checksum;
  EXPECT_GT(status.files[0].loaded_at_unix_s, 1'600'000'000);
  EXPECT_EQ(status.generation, 1);
  EXPECT_EQ(status.last_error, "");
}

TEST(EngineTest, Sha256IsTheDigestOfTheFileBytes) {
  TempDir dir;
  write_text(dir / "r.pl", "decide(_, _, add, r, \"r\").\n");
  Engine engine(options_for(dir));
  // printf 'decide(_, _, add, r, "r").\n' | sha256sum
  EXPECT_EQ(engine.status().files.at(0).sha256_or_checksum,
            "b1dabc0aa5992ed9aa8a2bc98a2ddbd244fabc4f94d6fdbc22da86d66eccbdd6");
}

TEST(EngineTest, HalfAMillionDecisionsInARowKeepWorking) {
  // Regression: the string buffers of PL_get_nchars() piled up and SWI-Prolog aborted the process
  // ("Too many stacked strings") after about 250 000 decisions.
  TempDir dir;
  write_text(dir / "r.pl", "decide(_, _, add, r, \"x\").\n");
  Engine engine(options_for(dir));
  const DecisionQuery query = unmatched();
  int wrong = 0;
  for (int i = 0; i < 500000; ++i) {
    if (engine.decide(query).fallback) ++wrong;
  }
  EXPECT_EQ(wrong, 0);
}

TEST(EngineTest, SecondEngineWithTheSameKnowledgeBaseThrows) {
  TempDir dir;
  copy_shipped_rules(dir);
  Engine first(options_for(dir));
  EXPECT_THROW(Engine second(options_for(dir)), RuleError);
  EXPECT_EQ(first.decide(unmatched()).rule, "unmatched_added");
}

// One process, two maps: each engine has its own facts, its own rules and its own reloads.
TEST(EngineTest, EnginesWithTheirOwnKnowledgeBasesKeepTheirFactsAndRulesApart) {
  TempDir shipped, other;
  copy_shipped_rules(shipped);
  write_text(other / "floor2.pl", "decide(_, _, add, floor2, \"floor 2 keeps everything\").\n");
  Engine first(options_for(shipped));
  auto second_options = options_for(other);
  second_options.knowledge_base = "wm_kb_floor2";
  auto second = std::make_unique<Engine>(second_options);

  first.set_floor_plan(demo_floor_plan());
  EXPECT_EQ(first.query("object(w1, K)", 10).solutions.size(), 1u);
  EXPECT_TRUE(second->query("object(O, K)", 10).solutions.empty());
  EXPECT_EQ(first.decide(matched("w1_e0", "w1")).rule, "solid_confirmed");
  EXPECT_EQ(second->decide(matched("w1_e0", "w1")).rule, "floor2");

  // A reload of one leaves the other's rules and generation as they were.
  write_text(other / "floor2.pl", "decide(_, _, add, floor2_v2, \"floor 2, second version\").\n");
  EXPECT_EQ(second->reload().generation, 2);
  EXPECT_EQ(second->decide(unmatched()).rule, "floor2_v2");
  EXPECT_EQ(first.status().generation, 1);
  EXPECT_EQ(first.decide(unmatched()).rule, "unmatched_added");

  // Gone, it leaves the first as it was; its knowledge base can be taken again, empty.
  second.reset();
  EXPECT_EQ(first.query("object(w1, K)", 10).solutions.size(), 1u);
  EXPECT_EQ(first.decide(matched("w1_e0", "w1")).rule, "solid_confirmed");
  Engine again(second_options);
  EXPECT_TRUE(again.query("object(O, K)", 10).solutions.empty());
  EXPECT_EQ(again.decide(unmatched()).rule, "floor2_v2");
}

TEST(EngineTest, TwoKnowledgeBasesDecideAndChangeTheirFactsOnTwoThreadsAtOnce) {
  TempDir shipped, other;
  copy_shipped_rules(shipped);
  copy_shipped_rules(other);
  Engine first(options_for(shipped));
  auto second_options = options_for(other);
  second_options.knowledge_base = "wm_kb_2";
  Engine second(second_options);
  // Each thread swaps its engine's plan between the demo plan and none, deciding a view of w1 after each swap:
  // the other engine's swaps must never show.
  const auto run = [](Engine& engine, int& wrong) {
    ThreadAttachment attached(engine);
    for (int i = 0; i < 300; ++i) {
      const bool with_plan = i % 2 == 0;
      engine.set_floor_plan(with_plan ? demo_floor_plan() : std::vector<ObjectFacts>{});
      // Without the plan w1 is no solid object to the rules, so its view is not confirmed as one.
      const bool confirmed = engine.decide(matched("w1_e0", "w1")).rule == "solid_confirmed";
      const auto objects = engine.query("object(O, K)", 10).solutions.size();
      if (confirmed != with_plan || objects != (with_plan ? 3u : 0u)) ++wrong;
    }
  };
  int wrong_first = 0, wrong_second = 0;
  std::thread a([&] { run(first, wrong_first); });
  std::thread b([&] { run(second, wrong_second); });
  a.join();
  b.join();
  EXPECT_EQ(wrong_first, 0);
  EXPECT_EQ(wrong_second, 0);
}

TEST(EngineTest, AKnowledgeBaseNameThatCouldBeAnotherModuleIsRefused) {
  TempDir dir;
  copy_shipped_rules(dir);
  auto options = options_for(dir);
  for (const char* name : {"", "user", "system", "lists", "wm_kb_", "wm_kbx", "wm_kb_A", "wm_kb_a-b", "wm_kb_a:b",
                           "wm_kb_12345678901234567890123456789012345678901234567890"}) {
    options.knowledge_base = name;
    EXPECT_THROW(Engine engine(options), std::invalid_argument) << name;
  }
  options.knowledge_base = "wm_kb_site_1_floor_2";
  Engine engine(options);
  EXPECT_EQ(engine.decide(unmatched()).rule, "unmatched_added");
}

TEST(EngineTest, InvalidOptionsAreRejected) {
  TempDir dir;
  copy_shipped_rules(dir);
  auto options = options_for(dir);
  options.inference_limit = 0;
  EXPECT_THROW(Engine engine(options), std::invalid_argument);
  options = options_for(dir);
  options.time_limit_s = std::nan("");
  EXPECT_THROW(Engine engine(options), std::invalid_argument);
}

TEST(EngineTest, MissingRulesDirectoryThrows) {
  TempDir dir;
  auto options = options_for(dir);
  options.rules_dir = dir / "missing";
  EXPECT_THROW(Engine engine(options), RuleError);
}

TEST(EngineTest, EmptyRulesDirectoryThrows) {
  TempDir dir;
  write_text(dir / "world_model.plt", ":- true.\n");
  try {
    Engine engine(options_for(dir));
    FAIL() << "expected RuleError";
  } catch (const RuleError& e) {
    EXPECT_NE(std::string(e.what()).find("no *.pl rule file"), std::string::npos) << e.what();
  }
}

TEST(EngineTest, SyntaxErrorAtConstructionThrowsWithFileAndLine) {
  TempDir dir;
  write_text(dir / "broken.pl",
             "% a comment\n"
             "decide(_, none, add, r, \"x\").\n"
             "decide(_, element(E, _, _), merge, r, E :- true.\n");
  try {
    Engine engine(options_for(dir));
    FAIL() << "expected RuleError";
  } catch (const RuleError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find((dir / "broken.pl").string() + ":3: "), std::string::npos) << message;
    EXPECT_NE(message.find("Syntax error"), std::string::npos) << message;
  }
}

TEST(EngineTest, FilesLoadInNameOrderAndPltFilesAreIgnored) {
  TempDir dir;
  write_text(dir / "10_helpers.pl", "answer(merge).\n");
  write_text(dir / "20_decide.pl", "decide(_, _, A, helper_rule, \"from helper\") :- answer(A).\n");
  write_text(dir / "20_decide.plt", "this is not Prolog\n");
  write_text(dir / ".#20_decide.pl", "neither is this\n");
  Engine engine(options_for(dir));
  const Decision decision = engine.decide(unmatched());
  EXPECT_EQ(decision.action, "merge");
  EXPECT_EQ(decision.rule, "helper_rule");
  const RulesStatus status = engine.status();
  ASSERT_EQ(status.files.size(), 2u);
  EXPECT_EQ(status.files[0].path, (dir / "10_helpers.pl").string());
  EXPECT_EQ(status.files[1].path, (dir / "20_decide.pl").string());
}

TEST(EngineTest, ExplanationGivenAsAtomOrTermIsText) {
  TempDir dir;
  write_text(dir / "r.pl",
             "decide(observation(atom, _, _, _), _, add, r1, 'an atom') :- !.\n"
             "decide(_, _, add, \"r2\", because(42)).\n");
  Engine engine(options_for(dir));
  EXPECT_EQ(engine.decide(unmatched("atom")).explanation, "an atom");
  const Decision decision = engine.decide(unmatched("other"));
  EXPECT_EQ(decision.rule, "r2");
  EXPECT_EQ(decision.explanation, "because(42)");
  EXPECT_FALSE(decision.fallback);
}

}  // namespace
}  // namespace wm::rules
