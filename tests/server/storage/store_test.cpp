#include "server/storage/store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

#include "server/storage/postgres.h"
#include "server/storage/sqlite.h"
#include "support/postgres_server.h"
#include "support/temp_dir.h"

namespace wm::storage {
namespace {

apriori::FloorPlan plan() {
  return apriori::parse_floor_plan_json(R"({"name": "p", "objects": [
      {"id": "w", "kind": "wall", "attributes": ["solid"], "segments": [[[0, 10], [20, 10]]]},
      {"id": "t", "kind": "table", "attributes": ["not_deformable"], "pose": {"x": 5, "y": 5, "theta": 0.3},
       "polygon": [[-0.6, -0.4], [0.6, -0.4], [0.6, 0.4], [-0.6, 0.4]]}]})");
}

world::UpdateResult add_element(const world::WorldState& state, std::int64_t seq) {
  world::Observation obs;
  obs.observer = "robot-1";
  obs.stamp_s = 3.25;
  auto s = fusion::LineSegment::from_points({1.0 / 3.0, 2}, {4, 2.1}, Eigen::Matrix2d::Identity());
  s.line.cov = world::midpoint_line_cov(s, 0.01, 0.01);
  obs.segments.push_back({s});
  return world::apply_observation(state, obs, seq, world::WorldOptions{}, [](const rules::DecisionQuery&) {
    return rules::Decision{"add", "r", "why", false};
  });
}

// Each engine the store runs on: the same tests, a SQLite file or a schema of a private PostgreSQL server.
enum class Engine { sqlite, postgresql };

class StoreTest : public ::testing::TestWithParam<Engine> {
 protected:
  /// The options of this test's store: a file in its directory, or its own schema.
  StoreOptions store_options() const {
    StoreOptions options;
    if (GetParam() == Engine::sqlite) {
      options.path = (dir_.path() / "a.db").string();
    } else {
      options.path = testing::postgres().uri();
      options.postgres_schema = testing::schema_for(::testing::UnitTest::GetInstance()->current_test_info()->name());
    }
    return options;
  }
  testing::TempDir dir_;
};

TEST_P(StoreTest, NewFileHasCurrentSchemaAndEmptyWorld) {
  Store store(store_options());
  EXPECT_EQ(store.schema_version(), Store::kSchemaVersion);
  const auto state = store.load(world::WorldOptions{});
  EXPECT_EQ(state.version, 0);
  EXPECT_TRUE(state.objects.empty());
  EXPECT_TRUE(state.elements.empty());
}

TEST_P(StoreTest, WorldSurvivesReopenBitForBit) {
  const auto path = store_options();
  world::WorldOptions options;
  world::WorldState saved;
  {
    Store store(path);
    auto loaded = world::apply_floor_plan(world::WorldState{}, plan(), options);
    // Move the table as a rigid update would, so the stored pose differs from the drawn one.
    auto table = loaded.state.objects[1];
    table.body = fusion::RigidObject({5.0 + 1e-3 / 7.0, 5.0, 0.3 + 1e-4}, Eigen::Matrix3d::Identity() * 1e-3,
                                     table.body.edges());
    loaded.state.objects.put(1, table);
    store.commit_floor_plan(loaded, plan());
    auto update = add_element(loaded.state, 1);
    store.commit_observation(update, world::Observation{"robot-1", "client", "unknown", 3.25, 0.0, {}},
                             R"({"segments": []})");
    saved = update.state;
  }
  Store store(path);
  const auto state = store.load(options);
  EXPECT_EQ(state.version, saved.version);
  EXPECT_EQ(state.next_element_number, 2);
  EXPECT_EQ(state.last_decision_seq, 1);
  ASSERT_EQ(state.objects.size(), 2u);
  EXPECT_EQ(state.objects[1].body.pose().x_m, saved.objects[1].body.pose().x_m);
  EXPECT_EQ(state.objects[1].body.pose().theta_rad, saved.objects[1].body.pose().theta_rad);
  ASSERT_EQ(state.elements.size(), 1u);
  const auto& a = state.elements.at(1).segment;
  const auto& b = saved.elements.at(1).segment;
  EXPECT_EQ(a.line.rho_m, b.line.rho_m);
  EXPECT_EQ(a.line.phi_rad, b.line.phi_rad);
  EXPECT_EQ(a.line.cov, b.line.cov);
  EXPECT_EQ(a.t0_m, b.t0_m);
  EXPECT_EQ(a.t1_m, b.t1_m);
  const auto& ma = state.elements.at(1).moments;
  const auto& mb = saved.elements.at(1).moments;
  EXPECT_GT(mb.weight, 3.0);
  EXPECT_EQ(ma.to_array(), mb.to_array());
  const auto log = store.decisions(0, 10);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_EQ(log[0].action, rules::Action::add);
  EXPECT_EQ(log[0].element, "e1");
  EXPECT_EQ(log[0].observer, "robot-1");
  EXPECT_EQ(store.decisions(0, 10, std::string("e1")).size(), 1u);
  EXPECT_TRUE(store.decisions(0, 10, std::string("e2")).empty());
  EXPECT_TRUE(store.decisions(1, 10).empty());
}

// The side a wall was seen from keeps the two faces of a thick wall apart after a restart as before it; unknown
// stays unknown (NULL), not 0 rad, and a thin surface seen from both sides stays so.
TEST_P(StoreTest, AnElementsFacingSurvivesReopenAndUnknownStaysUnknown) {
  const auto path = store_options();
  {
    Store store(path);
    auto update = add_element(world::WorldState{}, 1);
    auto element = update.state.elements.at(1);
    element.facing_rad = -1.25;
    update.state.elements.put(element);
    store.commit_observation(update, world::Observation{"r", "scan", "laser", 0, 0, {}}, "{}");
    auto second = add_element(update.state, 2);
    ASSERT_FALSE(second.state.elements.at(2).facing_rad.has_value());
    store.commit_observation(second, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}");
    auto third = add_element(second.state, 3);
    auto thin = third.state.elements.at(3);
    thin.both_ways = true;
    third.state.elements.put(thin);
    store.commit_observation(third, world::Observation{"r", "scan", "laser", 0, 0, {}}, "{}");
  }
  Store store(path);
  const auto state = store.load(world::WorldOptions{});
  ASSERT_EQ(state.elements.size(), 3u);
  EXPECT_EQ(state.elements.at(1).facing_rad, std::optional<double>(-1.25));
  EXPECT_FALSE(state.elements.at(2).facing_rad.has_value());
  EXPECT_FALSE(state.elements.at(1).both_ways || state.elements.at(2).both_ways);
  EXPECT_TRUE(state.elements.at(3).both_ways);
  EXPECT_FALSE(state.elements.at(3).facing_rad.has_value());
}

TEST_P(StoreTest, FailedCommitLeavesNothingBehind) {
  Store store(store_options());
  auto update = add_element(world::WorldState{}, 1);
  store.commit_observation(update, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}");
  // The same observation sequence again violates the journal's primary key: the transaction rolls back.
  auto again = add_element(update.state, 1);
  EXPECT_THROW(store.commit_observation(again, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}"),
               StorageError);
  const auto state = store.load(world::WorldOptions{});
  EXPECT_EQ(state.elements.size(), 1u);
  EXPECT_EQ(state.version, update.state.version);
  EXPECT_EQ(store.decisions(0, 10).size(), 1u);
}

// A small laser scan by robot "r" at `stamp_s`.
world::ScanObservation laser_scan(double stamp_s) {
  fusion::LaserScan laser;
  laser.sensor_pose = {1.5, -2.25, 0.3};
  laser.angle_min_rad = -1.0;
  laser.angle_increment_rad = 0.01;
  laser.ranges_m = {1.0, 2.0, std::numeric_limits<double>::infinity(), 0.1 + 0.2};
  laser.range_max_m = 30;
  world::ScanObservation scan;
  scan.observer = "r";
  scan.stamp_s = stamp_s;
  scan.scan = laser;
  scan.pose_cov = Eigen::Matrix3d::Identity() * 1e-4;
  return scan;
}

RequestRecord request(const std::string& id, std::int64_t seq) {
  return RequestRecord{id, "primitives", 42, seq, seq, 0, std::nullopt};
}

TEST_P(StoreTest, AScanIsJournaledWithItsLinesAndItsRequestIdInOneCommit) {
  Store store(store_options());
  const auto lines = add_element(world::WorldState{}, 1);
  const world::Observation observation{"r", "scan", "laser", 0, 0, {}};
  const RequestRecord record{"scan-1", "scan", -7, 1, lines.state.version, 1, 1};
  const auto scan = laser_scan(2.5);
  store.commit_scan({1, &scan}, ObservationEntry{lines, observation, R"({"scan": 1})"}, record);
  EXPECT_EQ(store.last_scan_seq(), 1);
  const auto journal = store.scans_after(0);
  ASSERT_EQ(journal.size(), 1u);
  ASSERT_TRUE(journal[0].scan);
  EXPECT_EQ(journal[0].scan->observer, "r");
  EXPECT_EQ(journal[0].scan->stamp_s, 2.5);
  EXPECT_EQ(std::get<fusion::LaserScan>(journal[0].scan->scan).ranges_m,
            std::get<fusion::LaserScan>(scan.scan).ranges_m);
  EXPECT_EQ(store.observation_decisions(1).size(), 1u);
  EXPECT_EQ(store.scans_missing_line_decisions(), 0);
  const auto found = store.find_request("scan-1");
  ASSERT_TRUE(found);
  EXPECT_EQ(found->kind, "scan");
  EXPECT_EQ(found->body_hash, -7);
  EXPECT_EQ(found->lines_seq, 1);
  EXPECT_EQ(found->version, lines.state.version);
  // A scan without lines.
  const auto second = laser_scan(3.0);
  store.commit_scan({2, &second}, std::nullopt);
  EXPECT_EQ(store.last_scan_seq(), 2);
  EXPECT_FALSE(store.find_request("scan-2"));
  // Read a page at a time, and one by its number.
  const auto third = laser_scan(3.5);
  store.commit_scan({3, &third}, std::nullopt);
  const auto page = store.scans_after(0, 2);
  ASSERT_EQ(page.size(), 2u);
  EXPECT_EQ(page[0].seq, 1);
  EXPECT_EQ(page[1].seq, 2);
  const auto rest = store.scans_after(page.back().seq, 2);
  ASSERT_EQ(rest.size(), 1u);
  EXPECT_EQ(rest[0].seq, 3);
  EXPECT_TRUE(store.scans_after(3, 2).empty());
  const auto by_number = store.scan(2);
  ASSERT_TRUE(by_number && by_number->scan);
  EXPECT_EQ(by_number->scan->stamp_s, 3.0);
  EXPECT_FALSE(store.scan(4));
}

TEST_P(StoreTest, AScanWhoseLinesFailToCommitLeavesNoJournalEntry) {
  Store store(store_options());
  const auto first = add_element(world::WorldState{}, 1);
  store.commit_observation(first, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}");
  // Lines with the observation sequence already taken: the line write fails, so the scan must not stay.
  const auto clash = add_element(first.state, 1);
  const world::Observation observation{"r", "scan", "laser", 0, 0, {}};
  const auto scan = laser_scan(0);
  EXPECT_THROW(store.commit_scan({1, &scan}, ObservationEntry{clash, observation, R"({"scan": 1})"},
                                 RequestRecord{"s", "scan", 1, 1, 2, 1, 1}),
               StorageError);
  EXPECT_EQ(store.last_scan_seq(), 0);
  EXPECT_FALSE(store.find_request("s"));
  EXPECT_EQ(store.decisions(0, 10).size(), 1u);
}

TEST_P(StoreTest, ARequestIdIsKeptOnlyWithItsEffectAndOnlyOnce) {
  Store store(store_options());
  auto update = add_element(world::WorldState{}, 1);
  store.commit_observation(update, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}", request("a", 1));
  // The effect fails (seq taken): the id is not stored either.
  auto clash = add_element(update.state, 1);
  EXPECT_THROW(
      store.commit_observation(clash, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}", request("b", 1)),
      StorageError);
  EXPECT_FALSE(store.find_request("b"));
  // The id is taken: the effect rolls back with it.
  auto next = add_element(update.state, 2);
  EXPECT_THROW(
      store.commit_observation(next, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}", request("a", 2)),
      StorageError);
  EXPECT_EQ(store.load(world::WorldOptions{}).last_observation_seq, 1);
  ASSERT_TRUE(store.find_request("a"));
  EXPECT_EQ(store.find_request("a")->seq, 1);
}

TEST_P(StoreTest, OnlyTheNewestRequestIdsAreKept) {
  StoreOptions options = store_options();
  options.request_ids_kept = 3;
  Store store(options);
  world::WorldState state;
  for (std::int64_t seq = 1; seq <= 5; ++seq) {
    auto update = add_element(state, seq);
    store.commit_observation(update, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}",
                             request("id-" + std::to_string(seq), seq));
    state = update.state;
  }
  EXPECT_FALSE(store.find_request("id-1"));
  EXPECT_FALSE(store.find_request("id-2"));
  for (const auto* id : {"id-3", "id-4", "id-5"}) EXPECT_TRUE(store.find_request(id)) << id;
}

TEST(SqliteStoreTest, MigratingASchema3FileLinksItsScansToTheirLineObservations) {
  testing::TempDir dir;
  const auto path = (dir.path() / "a.db").string();
  { Store store({path, true}); }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  // Back to schema 3 as version 3 wrote it: scan 1 with lines (observation 2), scan 2 without.
  const char* v3 = R"sql(
    DROP INDEX decisions_by_observation; DROP TABLE requests; ALTER TABLE scans DROP COLUMN lines_seq;
    ALTER TABLE scans DROP COLUMN scan;
    ALTER TABLE elements DROP COLUMN moments; ALTER TABLE elements DROP COLUMN facing; DROP TABLE placements;
    ALTER TABLE elements DROP COLUMN both_ways;
    DROP TABLE georeference;
    DROP TABLE robot_poses; DROP INDEX scans_by_observer; DROP TABLE plan_changes; DROP TABLE edge_beams;
    PRAGMA user_version = 3;
    INSERT INTO observations VALUES (1, 'client', 'r', 0, 0, '{}'), (2, 'scan', 'r', 0, 0, '{"scan": 1}');
    INSERT INTO scans VALUES (1, 'r', 'laser', 0, 0, '{}'), (2, 'r', 'laser', 0, 0, '{}');)sql";
  ASSERT_EQ(sqlite3_exec(db, v3, nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  sqlite3_close(db);
  Store store({path, true});
  EXPECT_EQ(store.schema_version(), Store::kSchemaVersion);
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "SELECT seq, lines_seq FROM scans ORDER BY seq", -1, &stmt, nullptr), SQLITE_OK);
  ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int64(stmt, 1), 2);
  ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_type(stmt, 1), SQLITE_NULL);
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  // Observation 2 has no decision: the one way a scan can be half applied, from a file written before schema 4.
  EXPECT_EQ(store.scans_missing_line_decisions(), 1);
  // Scans journaled before schema 10 keep the request body they came in, which start-up parses.
  const auto journal = store.scans_after(0);
  ASSERT_EQ(journal.size(), 2u);
  EXPECT_FALSE(journal[0].scan);
  EXPECT_EQ(journal[0].legacy_json, "{}");
}

TEST_P(StoreTest, RefusesADatabaseFromANewerVersion) {
  const auto options = store_options();
  { Store store(options); }
  if (GetParam() == Engine::sqlite) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(options.path.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "PRAGMA user_version = 99", nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
  } else {
    PostgresConnection(options.path, options.postgres_schema, false).exec("UPDATE schema_version SET version = 99");
  }
  try {
    Store store(options);
    FAIL() << "a newer schema must be refused";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("newer"), std::string::npos);
  }
}

// A PostgreSQL server that restarts (every connection cut) costs the store at most the commit that found out; the
// next one connects again, and nothing half-written is left.
TEST(PostgresStoreTest, AStoreConnectsAgainAfterTheDatabaseRestarted) {
  StoreOptions options;
  options.path = testing::postgres().uri();
  options.postgres_schema = "restarted";
  Store store(options);
  const auto first = add_element(world::WorldState{}, 1);
  store.commit_observation(first, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}");
  testing::postgres().restart();
  const auto second = add_element(first.state, 2);
  int failed = 0;
  for (int attempt = 0; attempt < 2; ++attempt) {
    try {
      store.commit_observation(second, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}");
      break;
    } catch (const StorageError&) {
      ++failed;  // the commit that found the connection gone
    }
  }
  EXPECT_LE(failed, 1);
  const auto state = store.load(world::WorldOptions{});
  EXPECT_EQ(state.elements.size(), 2u);
  EXPECT_EQ(state.last_observation_seq, 2);
  EXPECT_EQ(store.decisions(0, 10).size(), 2u);
}

INSTANTIATE_TEST_SUITE_P(Engines, StoreTest, ::testing::Values(Engine::sqlite, Engine::postgresql),
                         [](const auto& info) { return info.param == Engine::sqlite ? "sqlite" : "postgresql"; });

// Statements are compiled once per connection and SQL text and reused; these pin down what reuse must not change,
// on each engine.
class StatementTest : public StoreTest {
 protected:
  std::unique_ptr<Connection> connect() const {
    const auto options = store_options();
    if (GetParam() == Engine::sqlite) return std::make_unique<SqliteConnection>(options.path, true);
    return std::make_unique<PostgresConnection>(options.path, options.postgres_schema, true);
  }
};

TEST_P(StatementTest, AReusedStatementStartsFreshAndANestedOneGetsItsOwn) {
  const auto connection = connect();
  Connection& db = *connection;
  db.exec("CREATE TABLE t(k INTEGER PRIMARY KEY, v TEXT)");
  const std::string insert = "INSERT INTO t(k, v) VALUES (?1, ?2)";
  for (std::int64_t k = 1; k <= 3; ++k)
    Statement(db, insert).bind(1, k).bind(2, std::string_view("v" + std::to_string(k))).run();
  {
    // The cached statement's bindings were cleared: an unbound parameter is NULL, not the last run's value.
    Statement(db, "INSERT INTO t(k) VALUES (?1)").bind(1, std::int64_t{4}).run();
    Statement s(db, "SELECT v FROM t WHERE k = ?1");
    s.bind(1, std::int64_t{4});
    ASSERT_TRUE(s.step());
    EXPECT_EQ(s.column_optional_text(0), std::nullopt);
  }
  // A failed step (a duplicate key) leaves the cached statement usable.
  EXPECT_THROW(Statement(db, insert).bind(1, std::int64_t{1}).bind(2, std::string_view("again")).run(), StorageError);
  Statement(db, insert).bind(1, std::int64_t{5}).bind(2, std::string_view("v5")).run();
  // The same SELECT nested in a loop over its own rows: the inner one is a second statement, and the outer one
  // keeps its place.
  const std::string select = "SELECT k, v FROM t WHERE k >= ?1 ORDER BY k";
  std::vector<std::string> pairs;
  Statement outer(db, select);
  outer.bind(1, std::int64_t{4});
  while (outer.step()) {
    Statement inner(db, select);
    inner.bind(1, outer.column_int(0));
    ASSERT_TRUE(inner.step());
    pairs.push_back(std::to_string(outer.column_int(0)) + "=" + std::to_string(inner.column_int(0)));
  }
  EXPECT_EQ(pairs, (std::vector<std::string>{"4=4", "5=5"}));
  // A statement abandoned halfway (rows left) is reset when given back: the next one starts from the first row.
  {
    Statement s(db, select);
    s.bind(1, std::int64_t{1});
    ASSERT_TRUE(s.step());
  }
  Statement again(db, select);
  again.bind(1, std::int64_t{1});
  ASSERT_TRUE(again.step());
  EXPECT_EQ(again.column_int(0), 1);
  // The SQL text still names the statement in errors.
  try {
    Statement(db, "SELECT nope FROM t");
    FAIL() << "no error for a statement that does not compile";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("SELECT nope FROM t"), std::string::npos) << e.what();
  }
}

// What each engine gives back is what was bound: integers at their extremes, doubles to the last bit (and the
// infinities), text with quotes, placeholders and characters beyond ASCII, bytes of every value, and
// NULLs.
TEST_P(StatementTest, ValuesComeBackExactly) {
  const auto connection = connect();
  Connection& db = *connection;
  const bool postgresql = GetParam() == Engine::postgresql;
  db.exec(std::string("CREATE TABLE v(k BIGINT PRIMARY KEY, i BIGINT, d DOUBLE PRECISION, t TEXT, b ") +
          (postgresql ? "BYTEA" : "BLOB") + ")");
  const std::vector<std::int64_t> integers{std::numeric_limits<std::int64_t>::min(), -1, 0,
                                           std::numeric_limits<std::int64_t>::max()};
  const std::vector<double> doubles{0.1,
                                    1.0 / 3.0,
                                    -2.5e-300,
                                    std::numeric_limits<double>::denorm_min(),
                                    std::numeric_limits<double>::max(),
                                    std::numeric_limits<double>::infinity(),
                                    -std::numeric_limits<double>::infinity()};  // (SQLite keeps NaN as NULL)
  const std::string text = "it's \"?1\" $1 \\ Grüße 東京 ☃";
  std::string bytes;
  for (int value = 0; value < 256; ++value) bytes += static_cast<char>(value);
  const std::string insert = "INSERT INTO v(k, i, d, t, b) VALUES (?1, ?2, ?3, ?4, ?5)";
  for (std::size_t k = 0; k < doubles.size(); ++k) {
    Statement s(db, insert);
    s.bind(1, static_cast<std::int64_t>(k)).bind(2, integers[k % integers.size()]).bind(3, doubles[k]);
    s.bind(4, std::string_view(text)).bind_blob(5, bytes.data(), bytes.size()).run();
  }
  Statement(db, insert).bind(1, std::int64_t{100}).bind_null(2).bind_null(3).bind_null(4).bind_null(5).run();
  Statement s(db, "SELECT k, i, d, t, b FROM v ORDER BY k");
  for (std::size_t k = 0; k < doubles.size(); ++k) {
    ASSERT_TRUE(s.step());
    EXPECT_EQ(s.column_int(1), integers[k % integers.size()]);
    const double d = s.column_double(2);
    EXPECT_EQ(std::memcmp(&d, &doubles[k], sizeof d), 0) << k << ": " << d << " for " << doubles[k];
    EXPECT_EQ(s.column_text(3), text);
    ASSERT_EQ(s.column_bytes(4), bytes.size());
    EXPECT_EQ(std::string(static_cast<const char*>(s.column_blob(4)), s.column_bytes(4)), bytes);
  }
  ASSERT_TRUE(s.step());
  EXPECT_EQ(s.column_optional_int(1), std::nullopt);
  EXPECT_EQ(s.column_optional_double(2), std::nullopt);
  EXPECT_EQ(s.column_optional_text(3), std::nullopt);
  EXPECT_EQ(s.column_bytes(4), 0u);
  EXPECT_FALSE(s.step());
}

// A transaction whose write fails commits nothing, however its writes were sent (PostgreSQL sends them without
// waiting, and the failure comes at the commit), and the connection and its statements, those first made in the
// failed transaction too, serve the next one.
TEST_P(StatementTest, AFailedWriteInATransactionCommitsNothingAndTheNextTransactionWorks) {
  const auto connection = connect();
  Connection& db = *connection;
  db.exec("CREATE TABLE t(k BIGINT PRIMARY KEY, v TEXT)");
  Statement(db, "INSERT INTO t(k, v) VALUES (?1, 'first')").bind(1, std::int64_t{1}).run();
  const auto count = [&] {
    Statement s(db, "SELECT COUNT(*) FROM t");
    s.step();
    return s.column_int(0);
  };
  const std::string insert = "INSERT INTO t(k, v) VALUES (?1, ?2)";  // first made inside the failing transaction
  try {
    Transaction tx(db);
    Statement(db, insert).bind(1, std::int64_t{2}).bind(2, std::string_view("two")).run();
    Statement(db, insert).bind(1, std::int64_t{1}).bind(2, std::string_view("again")).run();  // the key is taken
    Statement(db, "UPDATE t SET v = 'changed' WHERE k = ?1").bind(1, std::int64_t{1}).run();
    tx.commit();
    FAIL() << "a duplicate key must fail the transaction";
  } catch (const StorageError& e) {
    const std::string what = e.what();  // SQLite: "UNIQUE constraint failed"; PostgreSQL: "duplicate key value"
    EXPECT_TRUE(what.find("UNIQUE") != std::string::npos || what.find("duplicate") != std::string::npos) << what;
  }
  EXPECT_EQ(count(), 1);
  {
    Transaction tx(db);
    Statement(db, insert).bind(1, std::int64_t{2}).bind(2, std::string_view("two")).run();
    // A read in the middle of a transaction sees its writes.
    Statement s(db, "SELECT v FROM t WHERE k = ?1");
    s.bind(1, std::int64_t{2});
    ASSERT_TRUE(s.step());
    EXPECT_EQ(s.column_text(0), "two");
    Statement(db, insert).bind(1, std::int64_t{3}).bind(2, std::string_view("three")).run();
    tx.commit();
  }
  EXPECT_EQ(count(), 3);
  // A transaction left without a commit (an exception in the caller) rolls back.
  {
    Transaction tx(db);
    Statement(db, insert).bind(1, std::int64_t{4}).bind(2, std::string_view("four")).run();
  }
  EXPECT_EQ(count(), 3);
}

INSTANTIATE_TEST_SUITE_P(Engines, StatementTest, ::testing::Values(Engine::sqlite, Engine::postgresql),
                         [](const auto& info) { return info.param == Engine::sqlite ? "sqlite" : "postgresql"; });

}  // namespace
}  // namespace wm::storage
