// WorldService without sockets: a real SQLite store and the shipped rules, a commit that fails in the store, and
// what the service puts back after it; the rules watcher's reloads, heard of through the diagnostics.
#include "server/service/world_service.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <thread>

#include "support/temp_dir.h"

namespace wm::service {
namespace {

world::Observation one_line(Eigen::Vector2d a, Eigen::Vector2d b) {
  world::Observation observation;
  observation.observer = "robot-1";
  auto s = fusion::LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
  s.line.cov = world::midpoint_line_cov(s, 0.01, 0.01);
  observation.segments.push_back({s});
  return observation;
}

// Another connection to the same file: what the store cannot prevent (a full disk, a file made read-only) made
// with a trigger that refuses every new observation.
void sql(const std::filesystem::path& path, const char* statement) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_busy_timeout(db, 5000);
  char* error = nullptr;
  const int rc = sqlite3_exec(db, statement, nullptr, nullptr, &error);
  const std::string message = error ? error : "";
  sqlite3_free(error);
  sqlite3_close(db);
  ASSERT_EQ(rc, SQLITE_OK) << message;
}

std::int64_t element_facts(WorldService& world) {
  const auto result = world.query("aggregate_all(count, element(_, _, _, _, _, _, _, _), N)", 1);
  EXPECT_EQ(result.solutions.size(), 1u);
  return result.solutions.empty() ? -1 : result.solutions[0][0].integer;
}

TEST(WorldServiceTest, AFailedCommitLeavesTheMapAndTheRulesAsCommittedAndTheNextRequestDecidesAsIfItNeverCame) {
  testing::TempDir dir;
  const auto path = dir.path() / "world.db";
  storage::Store store({path.string(), false});
  rules::Engine engine(rules::EngineOptions{WM_SOURCE_DIR "/rules/prolog"});
  common::Diagnostics diagnostics;
  WorldService world(ServiceOptions{}, store, engine, diagnostics);
  world.post_primitives(one_line({0, 0}, {4, 0}), "{}", std::nullopt);
  ASSERT_EQ(world.snapshot()->elements.size(), 1u);
  EXPECT_EQ(element_facts(world), 1);
  const auto version = world.snapshot()->version;

  sql(path, "CREATE TRIGGER refuse BEFORE INSERT ON observations BEGIN SELECT RAISE(ABORT, 'injected'); END;");
  EXPECT_THROW(world.post_primitives(one_line({0, 3}, {4, 3}), "{}", std::nullopt), storage::StorageError);
  // Nothing of it is seen: not in the map, not in the rules' facts (they had followed the decided map).
  EXPECT_EQ(world.snapshot()->version, version);
  EXPECT_EQ(world.snapshot()->elements.size(), 1u);
  EXPECT_EQ(element_facts(world), 1);

  sql(path, "DROP TRIGGER refuse;");
  const auto outcome = world.post_primitives(one_line({0, 3}, {4, 3}), "{}", std::nullopt);
  ASSERT_EQ(outcome.decisions.size(), 1u);
  EXPECT_EQ(outcome.decisions[0].action, rules::Action::add);
  // Numbered as in a run where the failed request never came: the decided-but-uncommitted map was dropped.
  EXPECT_EQ(outcome.decisions[0].element, std::optional<std::string>("e2"));
  EXPECT_EQ(outcome.version, version + 1);
  EXPECT_EQ(element_facts(world), 2);
}

// The watcher's reloads run on its own thread, where no caller hears of a failure: they go to the diagnostics.
TEST(WorldServiceTest, ARulesEditTheWatcherCannotLoadIsReportedAsAWarningAndAGoodOneAsInfo) {
  testing::TempDir dir;
  const auto rules_dir = dir.path() / "rules";
  std::filesystem::create_directories(rules_dir);
  std::filesystem::copy_file(WM_SOURCE_DIR "/rules/prolog/world_model.pl", rules_dir / "world_model.pl");
  storage::Store store({(dir.path() / "world.db").string(), false});
  rules::Engine engine(rules::EngineOptions{rules_dir});
  std::ostringstream echo;
  common::Diagnostics diagnostics("wmd: ", &echo);
  ServiceOptions options;
  options.watch_rules_dir = rules_dir;
  WorldService world(options, store, engine, diagnostics);
  const auto wait_for = [&diagnostics](auto&& done) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!done(diagnostics.summary()) && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    return done(diagnostics.summary());
  };

  std::ofstream(rules_dir / "zz_edit.pl") << "this is not ( prolog.\n";
  ASSERT_TRUE(wait_for([](const common::Diagnostics::Summary& s) { return s.total.warnings > 0; }));
  auto summary = diagnostics.summary();
  EXPECT_EQ(summary.by_where.at("rules").warnings, 1u);
  EXPECT_EQ(summary.total.errors, 0u);
  ASSERT_EQ(summary.recent.size(), 1u);
  EXPECT_EQ(summary.recent[0].where, "rules");
  EXPECT_NE(summary.recent[0].message.find("rules edit rejected"), std::string::npos);
  EXPECT_NE(echo.str().find("wmd: rules edit rejected"), std::string::npos);

  std::filesystem::remove(rules_dir / "zz_edit.pl");
  ASSERT_TRUE(wait_for([](const common::Diagnostics::Summary& s) { return s.total.info > 0; }));
  summary = diagnostics.summary();
  EXPECT_EQ(summary.by_where.at("rules").info, 1u);
  EXPECT_NE(summary.recent.back().message.find("rules reloaded"), std::string::npos);
  EXPECT_EQ(summary.total.warnings, 1u);
}

}  // namespace
}  // namespace wm::service
