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
