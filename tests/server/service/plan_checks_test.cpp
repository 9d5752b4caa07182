// PlanChecks with a real grid store (SQLite) and the shipped rules: evidence, verdicts, changes, rejections.
#include "server/service/plan_checks.h"

#include <gtest/gtest.h>

#include "server/service/knowledge_facts.h"
#include "server/service/service_test_helpers.h"
#include "support/temp_dir.h"

namespace wm::service {
namespace {

class PlanChecksTest : public ::testing::Test {
 protected:
  PlanChecksTest()
      : store_({(dir_.path() / "plan.db").string(), false}),
        grid_(GridStoreOptions{}, store_, diagnostics_),
        engine_(rules::EngineOptions{WM_SOURCE_DIR "/rules/prolog"}) {
    sync_all_facts(engine_, state_, world::WorldOptions{});
  }
  void drive(const world::ScanObservation& scan, int times) {
    for (int i = 0; i < times; ++i) grid_.insert(scan, ++seq_, state_);
  }

  testing::TempDir dir_;
  storage::Store store_;
  common::Diagnostics diagnostics_;
  GridStore grid_;
  rules::Engine engine_;
  world::WorldState state_ = wall_state();
  std::int64_t seq_ = 0;
};

TEST_F(PlanChecksTest, AWallTheLaserSawThroughIsMissingAndListedAsAChange) {
  drive(ring_scan(0, 5.0), 5);
  PlanChecks checks(PlanChecksOptions{}, grid_, engine_, diagnostics_);
  EXPECT_TRUE(checks.report()->edges.empty());  // nothing checked yet
  checks.refresh(state_, std::nullopt);
  const auto report = checks.report();
  EXPECT_EQ(report->grid_revision, 5);
  ASSERT_EQ(report->edges.size(), 1u);
  EXPECT_GT(report->edges[0].seen_through, 0.9);
  EXPECT_GT(report->edges[0].beams_through, 400);
  ASSERT_EQ(report->verdicts.size(), 1u);
  EXPECT_EQ(report->verdicts[0].object_id, "w");
  EXPECT_EQ(report->verdicts[0].verdict, "missing");
  EXPECT_EQ(report->verdicts[0].rule, "wall_missing");
  EXPECT_NE(report->verdicts[0].explanation.find("beams"), std::string::npos) << report->verdicts[0].explanation;
  auto changes = checks.changes(state_, report.get());
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].kind, world::ChangeKind::wall_missing);
  const auto id = changes[0].id;
  checks.reject(id);
  EXPECT_TRUE(checks.changes(state_, report.get()).empty());
  checks.unreject(id);
  ASSERT_EQ(checks.changes(state_, report.get()).size(), 1u);
  // Rejected before a restart (the ids come from the store): not listed.
  PlanChecks restarted(PlanChecksOptions{}, grid_, engine_, diagnostics_, {id});
  restarted.refresh(state_, std::nullopt);
  EXPECT_TRUE(restarted.changes(state_, restarted.report().get()).empty());
}

TEST_F(PlanChecksTest, AStandingWallIsBackedAndGetsNoVerdict) {
  drive(scan_of_standing_wall(), 5);
  PlanChecks checks(PlanChecksOptions{}, grid_, engine_, diagnostics_);
  checks.refresh(state_, std::nullopt);
  const auto report = checks.report();
  ASSERT_EQ(report->edges.size(), 1u);
  EXPECT_GT(report->edges[0].backed, 0.9);
  EXPECT_EQ(report->edges[0].beams_through, 0);
  EXPECT_TRUE(report->verdicts.empty());
  EXPECT_TRUE(checks.changes(state_, report.get()).empty());
}

TEST_F(PlanChecksTest, ARegionsCheckKeepsWhatLiesOutsideIt) {
  drive(ring_scan(0, 5.0), 5);
  PlanChecks checks(PlanChecksOptions{}, grid_, engine_, diagnostics_);
  checks.refresh(state_, std::nullopt);
  ASSERT_EQ(checks.report()->verdicts.size(), 1u);
  // A region far from the wall: its evidence and verdict stay as they were.
  checks.refresh(state_, world::Box{20, 20, 30, 30});
  EXPECT_EQ(checks.report()->edges.size(), 1u);
  EXPECT_EQ(checks.report()->verdicts.size(), 1u);
  // The wall is rebuilt and seen standing; a check of its region alone takes the verdict back.
  drive(scan_of_standing_wall(), 20);
  checks.refresh(state_, world::Box{1, -2, 3, 2});
  ASSERT_EQ(checks.report()->edges.size(), 1u);
  EXPECT_GT(checks.report()->edges[0].backed, 0.5);
  EXPECT_TRUE(checks.report()->verdicts.empty());
}

TEST(KnowledgeFactsTest, ObjectFactsCarryTheEdgesWhereTheyAreDrawnNow) {
  const auto state = wall_state(0.5);
  const auto facts = object_facts(state, world::WorldOptions{});
  ASSERT_EQ(facts.size(), 1u);
  EXPECT_EQ(facts[0].id, "w");
  EXPECT_EQ(facts[0].attributes, std::vector<std::string>{"solid"});
  ASSERT_EQ(facts[0].edges.size(), 1u);
  EXPECT_EQ(facts[0].edges[0].id, "w/0");
  EXPECT_NEAR(std::abs(facts[0].edges[0].rho_m), 2.5, 1e-9);
  EXPECT_NEAR(facts[0].edges[0].length_m, 2.0, 1e-9);
}

}  // namespace
}  // namespace wm::service
