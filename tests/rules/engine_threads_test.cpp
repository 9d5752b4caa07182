#include <gtest/gtest.h>

#include <atomic>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "rules/engine.h"
#include "tests/rules/rules_test_helpers.h"

namespace wm::rules {
namespace {

using testing::matched;
using testing::read_text;
using testing::replace_once;
using testing::unmatched;
using testing::write_text;

using EngineThreadsTest = testing::ShippedRulesTest;

TEST_F(EngineThreadsTest, DecisionFromAnAttachedSecondThreadWorks) {
  std::optional<Decision> decision;
  std::string error;
  std::thread worker([&] {
    try {
      ThreadAttachment attachment(engine_);
      decision = engine_.decide(matched("e7", "w1"));
    } catch (const std::exception& e) {
      error = e.what();
    }
  });
  worker.join();
  ASSERT_TRUE(decision.has_value()) << error;
  EXPECT_EQ(decision->action, "delete");
  EXPECT_EQ(decision->rule, "solid_confirmed");
}

TEST_F(EngineThreadsTest, UnattachedThreadGetsRuleErrorInsteadOfACrash) {
  std::string decide_error;
  std::string reload_error;
  std::thread worker([&] {
    try {
      engine_.decide(unmatched());
    } catch (const RuleError& e) {
      decide_error = e.what();
    }
    try {
      engine_.reload();
    } catch (const RuleError& e) {
      reload_error = e.what();
    }
  });
  worker.join();
  EXPECT_NE(decide_error.find("thread not attached"), std::string::npos) << decide_error;
  EXPECT_NE(reload_error.find("thread not attached"), std::string::npos) << reload_error;
}

TEST_F(EngineThreadsTest, AttachmentOnTheConstructingThreadIsHarmless) {
  {
    ThreadAttachment attachment(engine_);
    EXPECT_EQ(engine_.decide(unmatched()).rule, "unmatched_added");
  }
  EXPECT_EQ(engine_.decide(unmatched()).rule, "unmatched_added");
}

TEST_F(EngineThreadsTest, DecisionsDuringReloadsSeeOneRuleSetOrTheOther) {
  // Two deciders while the main thread flips the solid rule between delete and merge.
  const std::string delete_rules = read_text(dir_ / "world_model.pl");
  const std::string merge_rules = replace_once(delete_rules, "element(Element, Object, D2), delete, solid_confirmed,",
                                               "element(Element, Object, D2), merge, solid_confirmed,");
  std::atomic<bool> stop{false};
  std::atomic<int> bad{0};
  std::atomic<int> decisions{0};
  std::vector<std::thread> workers;
  for (int i = 0; i < 2; ++i) {
    workers.emplace_back([&] {
      ThreadAttachment attachment(engine_);
      while (!stop.load()) {
        const Decision d = engine_.decide(matched("e7", "w1"));
        if (d.fallback || d.rule != "solid_confirmed" || (d.action != "delete" && d.action != "merge")) ++bad;
        ++decisions;
      }
    });
  }
  for (int i = 0; i < 10; ++i) {
    write_text(dir_ / "world_model.pl", i % 2 == 0 ? merge_rules : delete_rules);
    engine_.reload();
  }
  stop = true;
  for (auto& worker : workers) worker.join();
  EXPECT_EQ(bad.load(), 0);
  EXPECT_GT(decisions.load(), 0);
  EXPECT_EQ(engine_.status().generation, 11);
}

TEST_F(EngineThreadsTest, FloorPlanReplacementIsAtomicForConcurrentDecisions) {
  // Plan A: w1 solid; plan B: w1 plain wall. A decision sees one or the other, never no w1.
  const std::vector<ObjectFacts> plan_a = {{"w1", "wall", {"solid"}, {{"w1_e0", 2.0, 0.0, 4.0}}}};
  const std::vector<ObjectFacts> plan_b = {{"w1", "wall", {}, {{"w1_e0", 2.0, 0.0, 4.0}}}};
  std::atomic<bool> stop{false};
  std::atomic<int> bad{0};
  std::thread worker([&] {
    ThreadAttachment attachment(engine_);
    while (!stop.load()) {
      const Decision d = engine_.decide(matched("w1_e0", "w1"));
      if (d.rule != "solid_confirmed" && d.rule != "apriori_confirmed") ++bad;
    }
  });
  for (int i = 0; i < 200; ++i) engine_.set_floor_plan(i % 2 == 0 ? plan_b : plan_a);
  stop = true;
  worker.join();
  EXPECT_EQ(bad.load(), 0);
}

}  // namespace
}  // namespace wm::rules
