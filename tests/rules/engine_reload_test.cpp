#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <string>

#include "rules/engine.h"
#include "tests/rules/rules_test_helpers.h"

namespace wm::rules {
namespace {

using testing::matched;
using testing::options_for;
using testing::read_text;
using testing::replace_once;
using testing::rules_with_first_clause;
using testing::TempDir;
using testing::unmatched;
using testing::write_text;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// Line (1-based) of the first occurrence of `part` in `text`.
int line_of(const std::string& text, const std::string& part) {
  const auto at = text.find(part);
  if (at == std::string::npos) return 0;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

// The shipped rules in a temp dir; tests edit the file there and reload.
class EngineReloadTest : public testing::ShippedRulesTest {
 protected:
  std::filesystem::path rules_file() const { return dir_ / "world_model.pl"; }

  // Expects reload() to throw RuleError and returns its message.
  std::string rejected_reload() {
    try {
      engine_.reload();
    } catch (const RuleError& e) {
      return e.what();
    }
    ADD_FAILURE() << "reload() accepted the rules";
    return "";
  }

  void expect_shipped_rules_still_active() {
    EXPECT_EQ(engine_.decide(matched("e7", "w1")).rule, "solid_confirmed");
    EXPECT_EQ(engine_.decide(matched("e8", std::nullopt)).rule, "unknown_element_merged");
    EXPECT_EQ(engine_.decide(unmatched()).rule, "unmatched_added");
  }
};

TEST_F(EngineReloadTest, BrokenEditIsRejectedWithFileAndLineAndOldRulesStayActive) {
  // The trap of a plain consult: the broken solid clause would be dropped and walls merged.
  const std::string good = read_text(rules_file());
  const std::string broken = replace_once(good, "    attribute(Object, solid),\n", "    attribute(Object, solid\n");
  write_text(rules_file(), broken);

  const std::string message = rejected_reload();
  EXPECT_TRUE(contains(message, rules_file().string() + ":")) << message;
  EXPECT_TRUE(contains(message, "Syntax error")) << message;

  expect_shipped_rules_still_active();
  const RulesStatus status = engine_.status();
  EXPECT_EQ(status.generation, 1);
  EXPECT_EQ(status.last_error, message);
}

TEST_F(EngineReloadTest, SyntaxErrorMessageGivesTheLineOfTheError) {
  const std::string good = read_text(rules_file());
  const std::string broken =
      replace_once(good, "unmatched_added, Explanation) :-", "unmatched_added, Explanation) :- )");
  write_text(rules_file(), broken);
  const std::string message = rejected_reload();
  const int line = line_of(broken, "unmatched_added, Explanation) :- )");
  ASSERT_GT(line, 0);
  EXPECT_TRUE(contains(message, rules_file().string() + ":" + std::to_string(line) + ": ")) << message;
}

TEST_F(EngineReloadTest, GoodEditFollowsAfterReloadOnly) {
  const std::string good = read_text(rules_file());
  write_text(rules_file(), replace_once(good, "element(Element, Object, D2), delete, solid_confirmed,",
                                        "element(Element, Object, D2), merge, solid_confirmed,"));
  EXPECT_EQ(engine_.decide(matched("e7", "w1")).action, "delete") << "not reloaded yet";

  const RulesStatus status = engine_.reload();
  EXPECT_EQ(status.generation, 2);

  const Decision decision = engine_.decide(matched("e7", "w1"));
  EXPECT_EQ(decision.action, "merge");
  EXPECT_EQ(decision.rule, "solid_confirmed");
}

TEST_F(EngineReloadTest, ReloadAfterRejectionClearsLastErrorAndUpdatesTheHash) {
  const std::string good = read_text(rules_file());
  const std::string old_hash = engine_.status().files.at(0).sha256_or_checksum;
  write_text(rules_file(), "decide(\n");
  rejected_reload();
  EXPECT_NE(engine_.status().last_error, "");

  write_text(rules_file(), good + "\n% edited\n");
  const RulesStatus status = engine_.reload();
  EXPECT_EQ(status.last_error, "");
  EXPECT_EQ(status.generation, 2);
  EXPECT_NE(status.files.at(0).sha256_or_checksum, old_hash);
}

TEST_F(EngineReloadTest, WarningsRejectTheReload) {
  write_text(dir_ / "zz_extra.pl", "helper(X) :- true.\n");
  const std::string message = rejected_reload();
  EXPECT_TRUE(contains(message, (dir_ / "zz_extra.pl").string() + ":1: ")) << message;
  EXPECT_TRUE(contains(message, "Singleton")) << message;
  expect_shipped_rules_still_active();
}

TEST_F(EngineReloadTest, RulesFileWithoutDecideIsRejected) {
  write_text(rules_file(), "other_fact(1).\n");
  const std::string message = rejected_reload();
  EXPECT_TRUE(contains(message, "decide/5")) << message;
  expect_shipped_rules_still_active();
}

TEST_F(EngineReloadTest, RulesFileCannotPutDecideIntoUser) {
  // The base(system) trap: with `user` as default import module, a rule module without decide/5
  // would pass the self-check through user:decide/5. Neither a directive nor a qualified clause can
  // put such a clause into user any more.
  write_text(rules_file(), ":- assertz(user:(decide(_, _, add, from_user, \"user\"))).\nother_fact(1).\n");
  EXPECT_TRUE(contains(rejected_reload(), "is not allowed in a rule file"));
  write_text(rules_file(), "user:decide(_, _, add, from_user, \"user\").\nother_fact(1).\n");
  EXPECT_TRUE(contains(rejected_reload(), "clauses for another module"));
  write_text(rules_file(), "other_fact(1).\n");
  EXPECT_TRUE(contains(rejected_reload(), "decide/5"));
  expect_shipped_rules_still_active();
}

TEST_F(EngineReloadTest, ExtraRuleFileDeclaringDecideMultifileGoesFirst) {
  write_text(dir_ / "00_glass.pl",
             ":- multifile decide/5.\n"
             "decide(observation(_, _, _, _), element(_, O, _), merge, glass_wall, \"glass\") :-\n"
             "    attribute(O, glass), !.\n");
  engine_.reload();
  engine_.set_floor_plan({{"g1", "wall", {"glass", "solid"}, {}}, {"w1", "wall", {"solid"}, {}}});
  EXPECT_EQ(engine_.decide(matched("e1", "g1")).rule, "glass_wall");
  EXPECT_EQ(engine_.decide(matched("e2", "w1")).rule, "solid_confirmed");
}

TEST_F(EngineReloadTest, SecondFileRedefiningDecideIsRejected) {
  write_text(dir_ / "zz_more.pl", "decide(_, _, add, more, \"more\").\n");
  const std::string message = rejected_reload();
  EXPECT_TRUE(contains(message, (dir_ / "zz_more.pl").string() + ":1: ")) << message;
  expect_shipped_rules_still_active();
}

TEST_F(EngineReloadTest, CallToAnUndefinedPredicateIsRejected) {
  // A typo (objct/2) in a clause that the self-check never reaches.
  write_text(dir_ / "00_glass.pl",
             ":- multifile decide/5.\n"
             "decide(observation(glass, _, _, _), element(_, O, _), delete, glass, \"g\") :-\n"
             "    objct(O, glass_wall).\n");
  const std::string message = rejected_reload();
  EXPECT_TRUE(contains(message, (dir_ / "00_glass.pl").string() + ":2: decide/5 calls the undefined predicate objct/2"))
      << message;
  expect_shipped_rules_still_active();
}

TEST_F(EngineReloadTest, ModuleFileIsRejected) {
  write_text(rules_file(), ":- module(my_rules, [decide/5]).\ndecide(_, _, add, r, \"r\").\n");
  const std::string message = rejected_reload();
  EXPECT_TRUE(contains(message, "module")) << message;
  expect_shipped_rules_still_active();
}

TEST_F(EngineReloadTest, RulesFailingACanonicalCaseAreRejected) {
  // Answers nothing for an unmatched observation.
  write_text(rules_file(), "decide(_, element(_, _, _), delete, r, \"r\").\n");
  const std::string message = rejected_reload();
  EXPECT_TRUE(contains(message, rules_file().string() + ":1: self-check 'unmatched'")) << message;
  expect_shipped_rules_still_active();
}

TEST_F(EngineReloadTest, RulesAnsweringANonAtomActionAreRejected) {
  write_text(rules_file(), "decide(_, _, do(it), r, \"r\").\n");
  EXPECT_TRUE(contains(rejected_reload(), "not an atom"));
  expect_shipped_rules_still_active();
}

TEST_F(EngineReloadTest, SelfCheckDoesNotTouchTheFloorPlan) {
  engine_.reload();
  EXPECT_EQ(engine_.decide(matched("e7", "w1")).rule, "solid_confirmed");
  EXPECT_TRUE(engine_.decide(matched("wm_check_e1", "wm_check_wall")).fallback)
      << "the canonical facts of the self-check leaked into wm_kb";
}

TEST_F(EngineReloadTest, DeletedRulesDirectoryIsRejected) {
  std::filesystem::remove_all(dir_.path());
  EXPECT_FALSE(rejected_reload().empty());
  expect_shipped_rules_still_active();
  std::filesystem::create_directories(dir_.path());
}

TEST_F(EngineReloadTest, LoopingRuleGivesTheFallbackAndFixedRulesWorkAfterReload) {
  write_text(rules_file(),
             rules_with_first_clause("decide(observation(spin, _, _, _), _, _, _, _) :- !, spin.", "spin :- spin."));
  engine_.reload();

  const auto start = std::chrono::steady_clock::now();
  const Decision decision = engine_.decide(unmatched("spin"));
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_TRUE(decision.fallback);
  EXPECT_EQ(decision.action, "add");
  EXPECT_EQ(decision.rule, "fallback");
  EXPECT_TRUE(contains(decision.explanation, "rules failed: ")) << decision.explanation;
  EXPECT_TRUE(contains(decision.explanation, "inference limit")) << decision.explanation;
  EXPECT_TRUE(contains(engine_.status().last_error, "inference limit")) << engine_.status().last_error;

  write_text(rules_file(),
             rules_with_first_clause("decide(observation(spin, _, _, _), _, merge, fixed, \"ok\") :- !."));
  engine_.reload();
  const Decision fixed = engine_.decide(unmatched("spin"));
  EXPECT_FALSE(fixed.fallback);
  EXPECT_EQ(fixed.rule, "fixed");
}

TEST(EngineTimeLimitTest, RuleLoopingPastTheTimeLimitGivesTheFallback) {
  TempDir dir;
  write_text(dir / "r.pl",
             rules_with_first_clause("decide(observation(spin, _, _, _), _, _, _, _) :- !, spin.", "spin :- spin."));
  auto options = options_for(dir);
  options.inference_limit = 1'000'000'000'000;  // only the time limit can stop it
  options.time_limit_s = 0.2;
  Engine engine(options);

  const auto start = std::chrono::steady_clock::now();
  const Decision decision = engine.decide(unmatched("spin"));
  const auto elapsed = std::chrono::steady_clock::now() - start;
  EXPECT_GE(elapsed, std::chrono::milliseconds(150));
  EXPECT_LT(elapsed, std::chrono::seconds(5));
  EXPECT_TRUE(decision.fallback);
  EXPECT_TRUE(contains(decision.explanation, "time limit")) << decision.explanation;
  EXPECT_EQ(engine.decide(unmatched("other")).rule, "custom");
}

TEST(EngineTimeLimitTest, RulesLoopingOnACanonicalCaseAreRejectedByReload) {
  TempDir dir;
  write_text(dir / "r.pl", "decide(_, _, add, r, \"r\").\n");
  auto options = options_for(dir);
  options.inference_limit = 1'000'000'000'000;
  options.time_limit_s = 0.2;
  Engine engine(options);
  write_text(dir / "r.pl", "decide(O, M, A, R, E) :- decide(O, M, A, R, E).\n");
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(engine.reload(), RuleError);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
  EXPECT_EQ(engine.decide(unmatched()).rule, "r");
}

TEST_F(EngineReloadTest, ThrowingRuleGivesTheFallback) {
  write_text(rules_file(),
             rules_with_first_clause("decide(observation(boom, _, _, _), _, _, _, _) :- !, atom_length(_, _)."));
  engine_.reload();
  const Decision decision = engine_.decide(unmatched("boom"));
  EXPECT_TRUE(decision.fallback);
  EXPECT_EQ(decision.action, "add");
  EXPECT_EQ(decision.rule, "fallback");
  EXPECT_TRUE(contains(decision.explanation, "rules failed: decide/5 raised")) << decision.explanation;
  EXPECT_TRUE(contains(decision.explanation, "instantiated")) << decision.explanation;
  EXPECT_EQ(engine_.status().last_error, decision.explanation.substr(std::string("rules failed: ").size()));

  EXPECT_EQ(engine_.decide(unmatched("calm")).rule, "custom");
}

TEST_F(EngineReloadTest, RuleThrowingAnArbitraryTermGivesTheFallback) {
  write_text(rules_file(),
             rules_with_first_clause("decide(observation(boom, _, _, _), _, _, _, _) :- !, throw(my_ball(1))."));
  engine_.reload();
  const Decision decision = engine_.decide(unmatched("boom"));
  EXPECT_TRUE(decision.fallback);
  EXPECT_TRUE(contains(decision.explanation, "my_ball(1)")) << decision.explanation;
}

TEST_F(EngineReloadTest, FailingRuleGivesTheFallback) {
  write_text(rules_file(), rules_with_first_clause("decide(observation(nothing, _, _, _), _, _, _, _) :- !, fail."));
  engine_.reload();
  const Decision decision = engine_.decide(unmatched("nothing"));
  EXPECT_TRUE(decision.fallback);
  EXPECT_TRUE(contains(decision.explanation, "decide/5 failed")) << decision.explanation;
}

TEST_F(EngineReloadTest, NonAtomActionGivesTheFallback) {
  write_text(rules_file(), rules_with_first_clause("decide(observation(odd, _, _, _), _, 42, r, \"x\") :- !."));
  engine_.reload();
  const Decision decision = engine_.decide(unmatched("odd"));
  EXPECT_TRUE(decision.fallback);
  EXPECT_EQ(decision.action, "add");
  EXPECT_TRUE(contains(decision.explanation, "not an atom: 42")) << decision.explanation;
}

TEST_F(EngineReloadTest, OtherAtomActionsArePassedThrough) {
  write_text(rules_file(),
             rules_with_first_clause("decide(observation(glass, _, _, _), _, ignore, glass_wall, \"g\") :- !."));
  engine_.reload();
  const Decision decision = engine_.decide(unmatched("glass"));
  EXPECT_FALSE(decision.fallback);
  EXPECT_EQ(decision.action, "ignore");
  EXPECT_EQ(decision.rule, "glass_wall");
}

}  // namespace
}  // namespace wm::rules
