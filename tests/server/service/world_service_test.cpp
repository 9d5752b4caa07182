// WorldService without sockets: a real SQLite store and the shipped rules, a commit that fails in the store, and
// what the service puts back after it; the rules watcher's reloads, heard of through the diagnostics.
#include "server/service/world_service.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <chrono>
#include <fstream>
#include <map>
#include <mutex>
#include <numbers>
#include <sstream>
#include <thread>

#include "server/service/service_test_helpers.h"
#include "support/temp_dir.h"

namespace wm::service {
namespace {

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

// A scan's commit has events from two threads' work (its lines' update on the writer, its grid region on the grid
// thread); with three robots posting at once, the next commit's update is ready before the grid has the scan. Live
// clients must still see each commit whole and in commit order, published by one thread.
TEST(WorldServiceTest, EachCommitsEventsComeTogetherFromOneThreadAndInCommitOrder) {
  testing::TempDir dir;
  storage::Store store({(dir.path() / "world.db").string(), false});
  rules::Engine engine(rules::EngineOptions{WM_SOURCE_DIR "/rules/prolog"});
  common::Diagnostics diagnostics("", nullptr);
  events::EventHub hub(1 << 16);
  WorldService world(ServiceOptions{}, store, engine, diagnostics, &hub);
  std::mutex mutex;
  std::vector<std::thread::id> publisher;  // of each event, in hub order
  const auto subscriber = hub.subscribe([&] {
    std::lock_guard lock(mutex);
    publisher.push_back(std::this_thread::get_id());
  });
  std::map<std::int64_t, std::int64_t> scan_of_observation;  // a scan's lines, observed as this observation
  std::vector<std::thread> robots;
  for (int r = 0; r < 3; ++r) {
    robots.emplace_back([&, r] {
      for (int i = 0; i < 40; ++i) {
        const auto outcome =
            world.post_scan(room_scan(2 + 0.15 * i, 2 + 2 * r, "robot-" + std::to_string(r)), "{}", std::nullopt);
        std::lock_guard lock(mutex);
        if (outcome.lines) scan_of_observation[outcome.lines->seq] = outcome.seq;
      }
    });
  }
  for (auto& robot : robots) robot.join();
  const auto events = subscriber->take();
  std::lock_guard lock(mutex);
  ASSERT_EQ(publisher.size(), events.size());
  ASSERT_GE(scan_of_observation.size(), 100u);
  std::int64_t last_scan = 0, last_observation = 0;
  std::size_t scans = 0, checked = 0;
  for (std::size_t i = 0; i < events.size(); ++i) {
    const auto event = nlohmann::json::parse(events[i].json);
    const auto type = event.at("type").get<std::string>();
    if (type == "scan") {
      EXPECT_GT(event.at("scan_seq").get<std::int64_t>(), last_scan) << "event " << i;
      last_scan = event.at("scan_seq").get<std::int64_t>();
      ++scans;
    }
    if (type != "update") continue;
    const auto observation = event.at("observation").get<std::int64_t>();
    EXPECT_GT(observation, last_observation) << "event " << i;
    last_observation = observation;
    const auto of_scan = scan_of_observation.find(observation);
    if (of_scan == scan_of_observation.end()) continue;  // a grid trim
    // The rest of the scan's commit: the robot heard from (maybe), then the scan's grid event, nothing between.
    std::size_t k = i + 1;
    while (k < events.size() && events[k].kind == events::EventKind::robot) ++k;
    ASSERT_LT(k, events.size());
    const auto next = nlohmann::json::parse(events[k].json);
    ASSERT_EQ(next.at("type"), "scan") << "the update of scan " << of_scan->second << " is followed by a "
                                       << next.at("type") << " event";
    EXPECT_EQ(next.at("scan_seq").get<std::int64_t>(), of_scan->second);
    for (std::size_t j = i; j <= k; ++j) EXPECT_EQ(publisher[j], publisher[i]) << "scan " << of_scan->second;
    ++checked;
  }
  EXPECT_EQ(scans, 120u);
  EXPECT_EQ(checked, scan_of_observation.size());
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
