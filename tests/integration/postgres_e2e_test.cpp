// wmd with its maps in PostgreSQL (--store): the same map as with SQLite, kept across a restart; GIS tools (ogrinfo,
// GDAL's PostgreSQL driver) read its elements from PostGIS as the API gives them; more maps are schemas of their own,
// dropped when removed; and a URI with a password, or a database that does not answer, is refused at start with a
// clear message.
#include <signal.h>

#include <chrono>
#include <regex>
#include <set>
#include <thread>

#include "e2e_fixture.h"
#include "grid_room.h"
#include "support/postgres_server.h"

namespace wm::testing {
namespace {

class PostgresStoreTest : public ServerFixture {
 protected:
  void SetUp() override {
    uri_ = postgres().uri();
    schema_ = schema_for(::testing::UnitTest::GetInstance()->current_test_info()->name());
    extra_args_ = {"--store", uri_, "--store-schema", schema_};
    start();
  }

  // host=… port=… user=wm dbname=worldmodel, from postgresql://wm@HOST:PORT/worldmodel.
  std::string libpq_keywords() const {
    const std::regex parts(R"(postgresql://(\w+)@([\d.]+):(\d+)/(\w+))");
    std::smatch m;
    EXPECT_TRUE(std::regex_match(uri_, m, parts)) << uri_;
    return "host=" + m[2].str() + " port=" + m[3].str() + " user=" + m[1].str() + " dbname=" + m[4].str();
  }
  // One value from the database (psql -tA).
  std::string query(const std::string& sql) const {
    const auto r = run_command("psql \"" + uri_ + "\" -tAX -c \"" + sql + "\"");
    EXPECT_EQ(r.status, 0) << r.output;
    auto out = r.output;
    while (!out.empty() && out.back() == '\n') out.pop_back();
    return out;
  }

  std::string uri_, schema_;
};

json segment(double x0, double y0, double x1, double y1) {
  return {{"p0", {x0, y0}}, {"p1", {x1, y1}}, {"cov", {{1e-4, 0}, {0, 1e-4}}}};
}

// The elements as ogrinfo reads them from the layer `elements` of `schema`: number -> the two endpoints.
std::map<std::int64_t, std::vector<double>> ogr_elements(const std::string& keywords, const std::string& schema) {
  const auto r = run_command("ogrinfo -ro -q -al PG:\"" + keywords + " schemas=" + schema + "\" elements");
  EXPECT_EQ(r.status, 0) << r.output;
  std::map<std::int64_t, std::vector<double>> found;
  // The primary key (the element's number) is the feature id: "OGRFeature(elements):12".
  const std::regex number(R"(OGRFeature\(elements\):(\d+))"),
      line(R"(LINESTRING \(([-\d.e]+) ([-\d.e]+),([-\d.e]+) ([-\d.e]+)\))");
  std::int64_t current = -1;
  std::istringstream lines(r.output);
  for (std::string text; std::getline(lines, text);) {
    std::smatch m;
    if (std::regex_search(text, m, number)) current = std::stoll(m[1].str());
    if (std::regex_search(text, m, line) && current >= 0)
      found[current] = {std::stod(m[1].str()), std::stod(m[2].str()), std::stod(m[3].str()), std::stod(m[4].str())};
  }
  return found;
}

TEST_F(PostgresStoreTest, TheMapIsKeptInPostgresAndGisToolsReadItsElementsAsTheApiGivesThem) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  send_json("POST", "/api/v1/primitives",
            {{"observer", "robot-1"}, {"segments", {segment(0.5, 0.4, 3.5, 0.45), segment(10, 3, 13, 3.02)}}});
  send_json("POST", "/api/v1/primitives", {{"observer", "robot-1"}, {"segments", {segment(0.6, 0.41, 3.6, 0.44)}}});
  // A laser scan: the journal, the grids and their flush go to the database too.
  for (int k = 0; k < 3; ++k) send_json("POST", "/api/v1/scans", grid_room::room_scan(4.0 + 0.1 * k, 3.0, 0.05 * k));
  const json elements = get_json("/api/v1/elements");
  const json decisions = get_json("/api/v1/decisions?limit=1000");
  const json grid = get_json("/api/v1/grid");
  ASSERT_GE(elements["elements"].size(), 3u);

  const auto ogr = ogr_elements(libpq_keywords(), schema_);
  ASSERT_EQ(ogr.size(), elements["elements"].size());
  for (const auto& e : elements["elements"]) {
    const auto id = e["id"].get<std::string>();
    const auto found = ogr.find(std::stoll(id.substr(1)));
    ASSERT_NE(found, ogr.end()) << id;
    const std::vector<double> api{e["p0"][0].get<double>(), e["p0"][1].get<double>(), e["p1"][0].get<double>(),
                                  e["p1"][1].get<double>()};
    for (std::size_t i = 0; i < 4; ++i) EXPECT_NEAR(found->second[i], api[i], 1e-9) << id << " coordinate " << i;
  }
  EXPECT_EQ(query("SELECT COUNT(*) FROM " + schema_ + ".objects WHERE geom IS NOT NULL"), "2");
  EXPECT_EQ(query("SELECT COUNT(*) FROM " + schema_ + ".scans"), "3");

  restart();
  EXPECT_EQ(get_json("/api/v1/elements"), elements);
  EXPECT_EQ(get_json("/api/v1/decisions?limit=1000"), decisions);
  EXPECT_EQ(get_json("/api/v1/grid"), grid);
  EXPECT_NE(server_->output().find("postgresql schema " + schema_), std::string::npos) << server_->output();
}

TEST_F(PostgresStoreTest, MoreMapsAreSchemasOfTheirOwnKeptAcrossARestartAndDroppedWhenRemoved) {
  send_json("POST", "/api/v1/maps", {{"id", "floor-2"}}, 201);
  EXPECT_EQ(query("SELECT COUNT(*) FROM pg_namespace WHERE nspname = 'map_floor-2'"), "1");
  send_json("POST", "/api/v1/maps/floor-2/primitives", {{"observer", "r"}, {"segments", {segment(1, 1, 4, 1)}}});
  EXPECT_EQ(query("SELECT COUNT(*) FROM \\\"map_floor-2\\\".elements"), "1");
  EXPECT_EQ(get_json("/api/v1/elements")["elements"].size(), 0u);

  restart();
  EXPECT_EQ(get_json("/api/v1/maps/floor-2/elements")["elements"].size(), 1u);
  EXPECT_EQ(send_json("DELETE", "/api/v1/maps/floor-2", json(nullptr))["deleted"], "floor-2");
  EXPECT_EQ(call("GET", "/api/v1/maps/floor-2/elements").status, 404);
  // Dropped when the last request that held it has ended.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (query("SELECT COUNT(*) FROM pg_namespace WHERE nspname = 'map_floor-2'") != "0" &&
         std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(query("SELECT COUNT(*) FROM pg_namespace WHERE nspname = 'map_floor-2'"), "0");
  restart();
  EXPECT_EQ(get_json("/api/v1/maps")["maps"].size(), 1u);
}

// A removal whose drop a crash prevented: the mark is committed, and the next start drops the schema.
TEST_F(PostgresStoreTest, AMapRemovedBeforeACrashIsDroppedAtTheNextStart) {
  send_json("POST", "/api/v1/maps", {{"id", "gone"}}, 201);
  send_json("POST", "/api/v1/maps/gone/primitives", {{"observer", "r"}, {"segments", {segment(1, 1, 4, 1)}}});
  query("INSERT INTO map_gone.meta(key, value) VALUES ('removed', 1)");  // what remove() commits first
  server_->crash();
  start();
  EXPECT_EQ(call("GET", "/api/v1/maps/gone/elements").status, 404);
  EXPECT_EQ(query("SELECT COUNT(*) FROM pg_namespace WHERE nspname = 'map_gone'"), "0");
}

// One node writes a map at a time: a second wmd on the same map is refused while the first holds its lease; after
// a clean stop it starts at once, after a kill -9 once the lease ran out (it waits), with the next epoch; and a node
// stopped (SIGSTOP) past its lease and resumed commits nothing: its writes are answered 503 lease_lost.
TEST_F(PostgresStoreTest, OneNodeWritesAMapAtATimeAndAPausedOwnerCommitsNothing) {
  ASSERT_EQ(server_->stop(), 0);
  const std::vector<std::string> common{"--port",         "0",     "--rules",        rules_dir_, "--store", uri_,
                                        "--store-schema", schema_, "--lease-ttl-ms", "900"};
  auto with = [&](std::vector<std::string> more) {
    more.insert(more.begin(), common.begin(), common.end());
    return more;
  };
  auto a = std::make_unique<WmdProcess>(with({"--node-id", "node-a"}));
  const std::string second = std::string(WM_WMD_PATH) + " --port 0 --rules " + rules_dir_ + " --store " + uri_ +
                             " --store-schema " + schema_ + " --node-id node-b";
  const auto refused = run_command(second);  // after waiting one lease time for it, in vain: a renews it
  EXPECT_EQ(refused.status, 1) << refused.output;
  EXPECT_NE(refused.output.find("held by node 'node-a'"), std::string::npos) << refused.output;
  ASSERT_EQ(a->stop(), 0);
  // Released at a clean stop: b starts at once.
  auto b = std::make_unique<WmdProcess>(with({"--node-id", "node-b"}));
  EXPECT_NE(b->output().find("node node-b, epoch"), std::string::npos) << b->output();
  b->crash();
  a = std::make_unique<WmdProcess>(with({"--node-id", "node-a"}));  // waits for b's lease to run out
  // Epochs: the fixture's own wmd 1, a 2, b 3, a again 4.
  EXPECT_NE(a->output().find("node node-a, epoch 4"), std::string::npos) << a->output();
  client::HttpClient to_a(a->url());
  EXPECT_EQ(to_a.request("POST", "/api/v1/primitives",
                         json{{"observer", "a"}, {"segments", {segment(0, 0, 3, 0)}}}.dump(), "application/json")
                .status,
            200);
  // a is paused past its lease; b takes the map over and writes; a, resumed, commits nothing.
  ::kill(a->pid(), SIGSTOP);
  std::this_thread::sleep_for(std::chrono::milliseconds(1200));
  b = std::make_unique<WmdProcess>(with({"--node-id", "node-b"}));
  client::HttpClient to_b(b->url());
  EXPECT_EQ(to_b.request("POST", "/api/v1/primitives",
                         json{{"observer", "b"}, {"segments", {segment(0, 5, 3, 5)}}}.dump(), "application/json")
                .status,
            200);
  ::kill(a->pid(), SIGCONT);
  const auto late =
      to_a.request("POST", "/api/v1/primitives", json{{"observer", "a"}, {"segments", {segment(0, 9, 3, 9)}}}.dump(),
                   "application/json");
  EXPECT_EQ(late.status, 503) << late.body;
  EXPECT_NE(late.body.find("lease_lost"), std::string::npos) << late.body;
  EXPECT_EQ(query("SELECT COUNT(*) FROM " + schema_ + ".elements"), "2");
  EXPECT_EQ(query("SELECT COUNT(*) FROM " + schema_ + ".observations WHERE observer = 'a'"), "1");
  EXPECT_EQ(to_b.request("GET", "/api/v1/elements").status, 200);
  a->crash();
}

TEST(PostgresStoreStartTest, APasswordOnTheCommandLineOrADatabaseThatDoesNotAnswerIsRefusedClearly) {
  const std::string wmd = WM_WMD_PATH;
  auto r = run_command(wmd + " --port 0 --store postgresql://wm:secret@127.0.0.1:5/worldmodel");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("PGPASSWORD"), std::string::npos) << r.output;
  r = run_command(wmd + " --port 0 --store 'postgresql://wm@127.0.0.1:5/worldmodel?password=secret'");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("password"), std::string::npos) << r.output;
  r = run_command(wmd + " --port 0 --store-schema 'x; DROP' --store postgresql://wm@127.0.0.1:5/worldmodel");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("--store-schema"), std::string::npos) << r.output;
  // Port 5: nothing listens. wmd ends with the reason, it does not hang or crash.
  r = run_command(wmd + " --port 0 --store postgresql://wm@127.0.0.1:5/worldmodel?connect_timeout=5");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("cannot connect to postgresql"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace wm::testing
