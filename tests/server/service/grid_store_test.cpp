// GridStore against a real SQLite store: inserts in journal order, the flush and the reload, gaps, and the beams
// counted at a plan's edges.
#include "server/service/grid_store.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <sstream>

#include "server/service/service_test_helpers.h"
#include "support/temp_dir.h"

namespace wm::service {
namespace {

GridStoreOptions options() {
  GridStoreOptions o;
  o.flush_interval = std::chrono::hours(1);  // only forced flushes
  return o;
}

storage::StoreOptions store_options(const testing::TempDir& dir) { return {(dir.path() / "grid.db").string(), false}; }

TEST(GridStoreTest, FlushedGridAndBeamCountsComeBackAfterAReload) {
  testing::TempDir dir;
  const auto state = wall_state();
  GridLayerValues before;
  std::int64_t beams_before = 0;
  {
    storage::Store store(store_options(dir));
    common::Diagnostics diagnostics;
    GridStore grid(options(), store, diagnostics);
    EXPECT_EQ(grid.revision(), 0);
    for (std::int64_t seq = 1; seq <= 5; ++seq) grid.insert(ring_scan(0, 5.0), seq, state);
    EXPECT_EQ(grid.revision(), 5);
    EXPECT_EQ(grid.last_scan_seq(), 5);
    grid.flush(false);  // within the interval: nothing written
    EXPECT_EQ(grid.flushed_scan_seq(), 0);
    grid.flush(true);
    EXPECT_EQ(grid.flushed_scan_seq(), 5);
    const auto bounds = grid.bounds();
    ASSERT_TRUE(bounds);
    before = grid.layer(fusion::GridLayer::bayes, *bounds);
    std::int64_t revision = 0;
    const auto evidence = grid.edge_evidence(state, std::nullopt, world::PlanEvidenceOptions{}, revision);
    ASSERT_EQ(evidence.size(), 1u);
    EXPECT_EQ(revision, 5);
    // The wall subtends 2·atan(0.5) = 53.1°: 106 beams of 0.5° per scan pass through it (they return at 5 m).
    EXPECT_NEAR(static_cast<double>(evidence[0].beams_through), 5 * 106.0, 5.0);
    EXPECT_EQ(evidence[0].beams_ended, 0);
    EXPECT_GT(evidence[0].seen_through, 0.9);
    beams_before = evidence[0].beams_through;
  }
  storage::Store store(store_options(dir));
  common::Diagnostics diagnostics;
  GridStore grid(options(), store, diagnostics);
  EXPECT_EQ(grid.revision(), 5);
  EXPECT_EQ(grid.flushed_scan_seq(), 5);
  const auto bounds = grid.bounds();
  ASSERT_TRUE(bounds);
  const auto after = grid.layer(fusion::GridLayer::bayes, *bounds);
  ASSERT_EQ(after.values.size(), before.values.size());
  for (std::size_t i = 0; i < after.values.size(); ++i) {
    if (std::isnan(before.values[i])) {
      EXPECT_TRUE(std::isnan(after.values[i])) << i;
    } else {
      EXPECT_FLOAT_EQ(after.values[i], before.values[i]) << i;
    }
  }
  std::int64_t revision = 0;
  const auto evidence = grid.edge_evidence(state, std::nullopt, world::PlanEvidenceOptions{}, revision);
  ASSERT_EQ(evidence.size(), 1u);
  EXPECT_EQ(evidence[0].beams_through, beams_before);
}

TEST(GridStoreTest, TheRevisionMovesOnlyThroughScansWhosePredecessorsAreIn) {
  testing::TempDir dir;
  storage::Store store(store_options(dir));
  common::Diagnostics diagnostics;
  GridStore grid(options(), store, diagnostics);
  const auto state = wall_state();
  grid.insert(ring_scan(0, 5.0), 2, state);  // the sonar port's scan 2 before the laser port's scan 1
  EXPECT_EQ(grid.revision(), 0);
  EXPECT_FALSE(grid.complete());
  grid.flush(true);  // nothing is written past a gap: the journal replays from the last flush at start
  EXPECT_EQ(grid.flushed_scan_seq(), 0);
  grid.insert(ring_scan(0, 5.0), 1, state);
  EXPECT_EQ(grid.revision(), 2);
  EXPECT_TRUE(grid.complete());
  grid.flush(true);
  EXPECT_EQ(grid.flushed_scan_seq(), 2);
}

TEST(GridStoreTest, AScanTheGridRefusesStillTakesItsPlaceInTheSequence) {
  testing::TempDir dir;
  storage::Store store(store_options(dir));
  common::Diagnostics diagnostics;
  GridStore grid(options(), store, diagnostics);
  auto bad = ring_scan(0, 5.0);
  std::get<fusion::LaserScan>(bad.scan).angle_increment_rad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(grid.insert(bad, 1, wall_state()), std::exception);
  EXPECT_EQ(grid.revision(), 1);
  grid.insert(ring_scan(0, 5.0), 2, wall_state());
  EXPECT_EQ(grid.revision(), 2);
}

TEST(GridStoreTest, BeamsItCannotCountAreReportedToTheDiagnosticsAndNotWrittenToStderr) {
  testing::TempDir dir;
  storage::Store store(store_options(dir));
  std::ostringstream echo;
  common::Diagnostics diagnostics("wmd: ", &echo);
  GridStore grid(options(), store, diagnostics);
  // A pose covariance the HTTP boundary would refuse: the grid takes the scan, the beam counting does not.
  auto bad = ring_scan(0, 5.0);
  bad.pose_cov(2, 2) = -1;
  std::ostringstream stderr_text;
  auto* const stderr_buffer = std::cerr.rdbuf(stderr_text.rdbuf());
  EXPECT_NO_THROW(grid.insert(bad, 1, wall_state()));
  grid.insert(ring_scan(0, 5.0), 2, wall_state());  // counted: nothing reported
  std::cerr.rdbuf(stderr_buffer);
  EXPECT_EQ(stderr_text.str(), "");
  EXPECT_EQ(grid.revision(), 2);
  const auto summary = diagnostics.summary();
  EXPECT_EQ(summary.total.warnings, 1u);
  EXPECT_EQ(summary.total.errors, 0u);
  ASSERT_TRUE(summary.by_where.contains("grid"));
  EXPECT_EQ(summary.by_where.at("grid").warnings, 1u);
  ASSERT_EQ(summary.recent.size(), 1u);
  EXPECT_EQ(summary.recent[0].severity, common::Severity::warning);
  EXPECT_NE(summary.recent[0].message.find("beams of a scan not counted at the plan's edges"), std::string::npos);
  EXPECT_EQ(echo.str().rfind("wmd: beams of a scan not counted", 0), 0u) << echo.str();
}

TEST(GridStoreTest, BeamsCountedWhereAnEdgeStoodDoNotFollowItWhenItMoves) {
  testing::TempDir dir;
  storage::Store store(store_options(dir));
  common::Diagnostics diagnostics;
  GridStore grid(options(), store, diagnostics);
  for (std::int64_t seq = 1; seq <= 4; ++seq) grid.insert(ring_scan(0, 5.0), seq, wall_state());
  // The plan is placed 0.5 m further: the counts were of another line of the world.
  const auto moved = wall_state(0.5);
  std::int64_t revision = 0;
  auto evidence = grid.edge_evidence(moved, std::nullopt, world::PlanEvidenceOptions{}, revision);
  ASSERT_EQ(evidence.size(), 1u);
  EXPECT_EQ(evidence[0].beams_through, 0);
  grid.insert(ring_scan(0, 5.0), 5, moved);  // counted again from here, at the new place
  evidence = grid.edge_evidence(moved, std::nullopt, world::PlanEvidenceOptions{}, revision);
  ASSERT_EQ(evidence.size(), 1u);
  EXPECT_GT(evidence[0].beams_through, 50);
  EXPECT_LT(evidence[0].beams_through, 120);  // one scan's, not five
}

TEST(GridStoreTest, ChangedRegionCoversTheScanUpToItsReturns) {
  testing::TempDir dir;
  storage::Store store(store_options(dir));
  common::Diagnostics diagnostics;
  GridStore grid(options(), store, diagnostics);
  const auto box = grid.changed_region(ring_scan(1.0, 3.0), 0.1);
  EXPECT_LE(box.min().x(), 1.0 - 3.0 - 0.1 + 1e-6);
  EXPECT_GE(box.max().x(), 1.0 + 3.0 + 0.1 - 1e-6);
  EXPECT_LT(box.max().x(), 1.0 + 3.0 + 0.5);
}

}  // namespace
}  // namespace wm::service

namespace wm::service {
namespace {

// The grid trim's probe of an element: a wall the laser hit several times is backed on it (and within a cell of it),
// free space the beams crossed is contrary, and what no beam reached is unknown. Occupied is P > 0.65.
TEST(GridStoreTest, TheElementProbeTellsBackedFromSeenFreeFromUnknown) {
  EXPECT_DOUBLE_EQ(kOccupiedLogOdds, std::log(0.65 / 0.35));
  fusion::OccupancyGrid grid(fusion::GridOptions{});
  const auto scan = std::get<fusion::LaserScan>(ring_scan(0, 3.0).scan);  // a circle of returns 3 m around (0, 0)
  for (int i = 0; i < 5; ++i) grid.insert(scan);
  fusion::OccupancyGrid::CellReader cells(grid);
  const auto probe = grid_element_probe(cells, grid.resolution_m());
  EXPECT_EQ(probe({3.0, 0.0}), world::GridEvidence::backed);
  EXPECT_EQ(probe({3.04, 0.0}), world::GridEvidence::backed);  // within a cell
  EXPECT_EQ(probe({1.5, 0.0}), world::GridEvidence::contrary);
  EXPECT_EQ(probe({10.0, 10.0}), world::GridEvidence::unknown);
}

}  // namespace
}  // namespace wm::service
