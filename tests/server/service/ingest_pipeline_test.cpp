// The ingest pipeline without sockets: the parts it writes through built by hand (a real SQLite store, the shipped
// rules, the grids), and scans posted to it as the HTTP handlers do.
#include "server/service/ingest_pipeline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <thread>

#include "server/service/service_errors.h"
#include "server/service/service_test_helpers.h"
#include "support/temp_dir.h"

namespace wm::service {
namespace {

struct IngestPipelineTest : ::testing::Test, WriterParts {
  RobotRegistry robots;
  GridStore grid{GridStoreOptions{}, store, diagnostics};
  PlanChecks plan_checks{PlanChecksOptions{}, grid, engine, diagnostics, {}};

  std::unique_ptr<IngestPipeline> start(IngestOptions options = {}) {
    return std::make_unique<IngestPipeline>(
        options, IngestParts{store, engine, writer, grid, plan_checks, robots, events, diagnostics});
  }
};

TEST_F(IngestPipelineTest, AScanIsJournaledDecidedAndInTheGridBeforeItsAnswerLeaves) {
  auto ingest = start();
  const auto outcome = ingest->post_scan(room_scan(5, 4), "{\"scan\": 1}", std::nullopt);
  EXPECT_EQ(outcome.seq, 1);
  EXPECT_FALSE(outcome.replayed);
  // Answered: journaled, its lines in the published map, and in the grid.
  EXPECT_EQ(store.last_scan_seq(), 1);
  EXPECT_EQ(grid.revision(), 1);
  ASSERT_TRUE(outcome.lines.has_value());
  EXPECT_GE(outcome.lines->decisions.size(), 4u);     // the room's four walls (one may come in two pieces)
  EXPECT_EQ(writer.snapshot()->elements.size(), 4u);  // ... which are four elements
  EXPECT_EQ(writer.snapshot()->version, outcome.lines->version);
  // The robot is where its scan was taken.
  const auto robot = robots.find("robot-1");
  ASSERT_TRUE(robot && robot->pose);
  EXPECT_NEAR(robot->pose->x, 5, 1e-9);
  EXPECT_NEAR(robot->pose->y, 4, 1e-9);
}

TEST_F(IngestPipelineTest, ARetriedRequestIdIsAnsweredAsTheFirstTimeAndAnotherBodyUnderItIsAConflict) {
  auto ingest = start();
  const auto first = ingest->post_scan(room_scan(5, 4), "{\"a\": 1}", "req-1");
  const auto retried = ingest->post_scan(room_scan(5, 4), "{\"a\": 1}", "req-1");
  EXPECT_TRUE(retried.replayed);
  EXPECT_EQ(retried.seq, first.seq);
  ASSERT_TRUE(first.lines && retried.lines);
  EXPECT_EQ(retried.lines->version, first.lines->version);
  EXPECT_EQ(store.last_scan_seq(), 1);  // not applied twice
  EXPECT_THROW(ingest->post_scan(room_scan(5, 4), "{\"a\": 2}", "req-1"), RequestIdConflict);
  EXPECT_EQ(store.last_scan_seq(), 1);
}

TEST_F(IngestPipelineTest, ACommandRunsOnTheWriterThreadAfterWhatWasPostedBeforeIt) {
  auto ingest = start();
  ingest->post_scan(room_scan(5, 4), "{}", std::nullopt);
  const auto [thread, version] = ingest->run_command([&] {
    return std::pair{std::this_thread::get_id(), writer.snapshot()->version};
  });
  EXPECT_NE(thread, std::this_thread::get_id());
  EXPECT_GE(version, 1);
  // Its result and its exception come back to the caller.
  EXPECT_THROW(ingest->run_command([]() -> int { throw std::invalid_argument("no"); }), std::invalid_argument);
}

TEST_F(IngestPipelineTest, WithScanLinesOffAScanOnlyFillsTheGrid) {
  IngestOptions options;
  options.extract_scan_lines = false;
  auto ingest = start(options);
  const auto outcome = ingest->post_scan(room_scan(5, 4), "{}", std::nullopt);
  EXPECT_FALSE(outcome.lines.has_value());
  EXPECT_EQ(grid.revision(), 1);
  EXPECT_TRUE(writer.snapshot()->elements.empty());
}

// A 720-beam scan from (x, 0) of one wall along y = 1.5 from x = −1 to x = 14 m: past x ≈ 8.5 m the laser meets it
// at under 10°, its returns 0.25–0.75 m apart, and the scan-line extractor makes nothing of them.
world::ScanObservation corridor_scan(double x) {
  return laser_scan(x, 0, 20, [&](double c, double s) {
    const double range = s > 1e-9 ? 1.5 / s : 1e9;
    const double at = x + range * c;
    return at >= -1 && at <= 14 && range < 20 ? range : 20.0;
  });
}

// The far end of the one element along the corridor wall [m].
double wall_reach_x(const world::WorldState& state) {
  double reach = -1e9;
  for (const auto& [number, e] : state.elements)
    if (std::abs(e.segment.p0().y() - 1.5) < 0.05 && std::abs(e.segment.p1().y() - 1.5) < 0.05)
      reach = std::max({reach, e.segment.p0().x(), e.segment.p1().x()});
  return reach;
}

TEST_F(IngestPipelineTest, AWallSeenAtAGrazingAngleGrowsAlongItsLineThroughTheSparseReturns) {
  auto ingest = start();
  ingest->post_scan(corridor_scan(0), "{\"scan\": 1}", std::nullopt);
  const double extracted = wall_reach_x(*writer.snapshot());
  EXPECT_LT(extracted, 9.5);  // the extractor's line ends where the returns fall apart
  ingest->post_scan(corridor_scan(0.1), "{\"scan\": 2}", std::nullopt);
  const auto state = writer.snapshot();
  EXPECT_GT(wall_reach_x(*state), 11.0);  // the second scan carries it on along its line
  EXPECT_LE(wall_reach_x(*state), 14.01);
  std::size_t on_wall = 0;
  for (const auto& [number, e] : state->elements) on_wall += std::abs(e.segment.p0().y() - 1.5) < 0.05 ? 1 : 0;
  EXPECT_EQ(on_wall, 1u);  // one element, not a second one beside the first
}

TEST_F(IngestPipelineTest, WithoutLineContinuationTheGrazingReturnsAddNothing) {
  IngestOptions options;
  options.continue_lines = false;
  auto ingest = start(options);
  ingest->post_scan(corridor_scan(0), "{}", std::nullopt);
  ingest->post_scan(corridor_scan(0.1), "{}", std::nullopt);
  EXPECT_LT(wall_reach_x(*writer.snapshot()), 9.5);
}

TEST_F(IngestPipelineTest, AScanFromASensorTheNetworkDoesNotTakeIsRefusedAndChangesNothing) {
  IngestOptions options;
  options.network_file = std::filesystem::path(WM_SOURCE_DIR "/networks/laser_only.yaml");
  auto ingest = start(options);
  EXPECT_TRUE(ingest->accepts_scans("laser"));
  EXPECT_FALSE(ingest->accepts_scans("sonar"));
  world::ScanObservation sonar;
  sonar.observer = "robot-1";
  fusion::SonarScan s;
  s.sensor_pose = {5, 4, 0};
  sonar.scan = s;
  EXPECT_THROW(ingest->post_scan(std::move(sonar), "{}", std::nullopt), std::invalid_argument);
  EXPECT_EQ(store.last_scan_seq(), 0);
}

}  // namespace
}  // namespace wm::service
