// Several maps in one wmd: made, listed, kept apart, kept across a restart, deleted; the routes of one map under
// /api/v1/maps/{map}/ against hostile ids and paths; two real drives replayed at once into two maps, each equal to
// the same drive replayed alone.
#include <sqlite3.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <set>
#include <thread>

#include "e2e_fixture.h"
#include "logs/carmen_log_reader.h"
#include "logs/scan_body.h"
#include "tools/raycast/raycast.h"

namespace wm::testing {
namespace {

json segment(double x0, double y0, double x1, double y1) { return {{"p0", {x0, y0}}, {"p1", {x1, y1}}}; }

std::set<std::string> map_ids(const json& list) {
  std::set<std::string> ids;
  for (const auto& m : list["maps"]) ids.insert(m["id"].get<std::string>());
  return ids;
}

class MapsTest : public ServerFixture {
 protected:
  std::filesystem::path maps_dir() const { return dir_.path() / "wm.db.maps"; }
};

TEST_F(MapsTest, MapsAreMadeListedKeptApartAcrossARestartAndDeleted) {
  EXPECT_EQ(map_ids(get_json("/api/v1/maps")), (std::set<std::string>{"default"}));
  EXPECT_FALSE(std::filesystem::exists(maps_dir())) << "made only when the first map is";

  const json made = send_json("POST", "/api/v1/maps", {{"id", "floor2"}}, 201);
  EXPECT_EQ(made["id"], "floor2");
  EXPECT_EQ(made["href"], "/api/v1/maps/floor2");
  EXPECT_TRUE(std::filesystem::exists(maps_dir() / "floor2.db"));
  EXPECT_EQ(call("POST", "/api/v1/maps", json{{"id", "floor2"}}.dump()).status, 409);
  EXPECT_EQ(call("POST", "/api/v1/maps", json{{"id", "default"}}.dump()).status, 409);

  // The plan and an observation go to floor2 only.
  send_json("PUT", "/api/v1/maps/floor2/floorplan", lab_plan());
  const json added = send_json("POST", "/api/v1/maps/floor2/primitives",
                               {{"source", "robot-2"}, {"segments", {segment(10, 3, 13, 3.02)}}});
  ASSERT_EQ(added["decisions"].size(), 1u);
  EXPECT_EQ(added["decisions"][0]["action"], "add");
  // The default map gets an observation of its own, elsewhere.
  send_json("POST", "/api/v1/primitives", {{"source", "robot-1"}, {"segments", {segment(0, 0, 0, 4)}}});

  const json floor2 = get_json("/api/v1/maps/floor2/map");
  const json default_map = get_json("/api/v1/map");
  EXPECT_EQ(floor2["objects"].size(), 2u);
  EXPECT_EQ(floor2["elements"].size(), 1u);
  EXPECT_EQ(default_map["objects"].size(), 0u);
  ASSERT_EQ(default_map["elements"].size(), 1u);
  EXPECT_DOUBLE_EQ(default_map["elements"][0]["p1"][1].get<double>(), 4.0);
  // "default" under /api/v1/maps/ is the default map.
  EXPECT_EQ(get_json("/api/v1/maps/default/elements"), get_json("/api/v1/elements"));
  // Each map's robots, decisions and health are its own.
  EXPECT_EQ(get_json("/api/v1/maps/floor2/robots")["robots"][0]["id"], "robot-2");
  EXPECT_EQ(get_json("/api/v1/robots")["robots"][0]["id"], "robot-1");
  EXPECT_EQ(get_json("/api/v1/maps/floor2/health")["objects"], 2);
  EXPECT_EQ(get_json("/api/v1/health")["objects"], 0);

  const json list = get_json("/api/v1/maps");
  ASSERT_EQ(list["maps"].size(), 2u);
  EXPECT_EQ(list["maps"][0]["id"], "default");
  EXPECT_EQ(list["maps"][1]["id"], "floor2");
  EXPECT_EQ(list["maps"][1]["objects"], 2);
  EXPECT_EQ(list["maps"][1]["elements"], 1);
  EXPECT_EQ(list["maps"][1]["robots"], 1);

  restart();
  EXPECT_EQ(get_json("/api/v1/maps/floor2/map")["elements"], floor2["elements"]);
  EXPECT_EQ(get_json("/api/v1/maps/floor2/map")["objects"], floor2["objects"]);
  EXPECT_EQ(get_json("/api/v1/map")["elements"], default_map["elements"]);

  // A delete takes the map and its file; the default map is untouched.
  EXPECT_EQ(send_json("DELETE", "/api/v1/maps/floor2", json(nullptr))["deleted"], "floor2");
  EXPECT_EQ(call("GET", "/api/v1/maps/floor2/map").status, 404);
  EXPECT_EQ(call("GET", "/api/v1/maps/floor2").status, 404);
  EXPECT_EQ(call("DELETE", "/api/v1/maps/floor2").status, 404);
  EXPECT_FALSE(std::filesystem::exists(maps_dir() / "floor2.db"));
  EXPECT_EQ(get_json("/api/v1/map")["elements"], default_map["elements"]);
  EXPECT_EQ(map_ids(get_json("/api/v1/maps")), (std::set<std::string>{"default"}));
  // Made again under the same id, it is a new, empty map (its cached map bytes are not the old map's).
  send_json("POST", "/api/v1/maps", {{"id", "floor2"}}, 201);
  EXPECT_TRUE(get_json("/api/v1/maps/floor2/map")["elements"].empty());
  restart();
  EXPECT_TRUE(get_json("/api/v1/maps/floor2/map")["elements"].empty());
}

// Hostile ids and paths: each is refused with its status and a JSON error, and nothing is made or changed.
TEST_F(MapsTest, BadIdsUnknownMapsAndServerRoutesUnderAMapAreRefusedAndChangeNothing) {
  send_json("POST", "/api/v1/maps", {{"id", "a"}}, 201);
  const auto files_before = [&] {
    std::set<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(maps_dir()))
      names.insert(entry.path().filename().string());
    return names;
  };
  const auto before = files_before();
  for (const json& bad : {json{{"id", "Floor2"}}, json{{"id", ""}}, json{{"id", "-x"}}, json{{"id", "_x"}},
                          json{{"id", "a/b"}}, json{{"id", "../etc"}}, json{{"id", std::string(33, 'a')}},
                          json{{"id", "a b"}}, json{{"id", "é"}}, json{{"id", 7}}, json{{"id", nullptr}},
                          json{{"name", "x"}}, json{{"id", "x"}, {"extra", 1}}, json::array(), json("x")}) {
    const auto r = call("POST", "/api/v1/maps", bad.dump());
    EXPECT_EQ(r.status, 400) << bad.dump() << " -> " << r.body;
    EXPECT_EQ(json::parse(r.body)["error"], "bad_request") << bad.dump();
  }
  EXPECT_EQ(call("POST", "/api/v1/maps", "{not json").status, 400);
  EXPECT_EQ(files_before(), before);

  // Under a map: a bad id is 400, an unknown map 404, and the map's own routes only.
  for (const std::string& target :
       std::vector<std::string>{"/api/v1/maps/Bad/map", "/api/v1/maps/-x/map", "/api/v1/maps/%2e%2e/map",
                                "/api/v1/maps/" + std::string(33, 'a') + "/map"}) {
    const auto r = call("GET", target);
    EXPECT_EQ(r.status, 400) << target << " -> " << r.body;
  }
  EXPECT_EQ(call("GET", "/api/v1/maps/nope/map").status, 404);
  EXPECT_EQ(json::parse(call("GET", "/api/v1/maps/nope/map").body)["error"], "map_not_found");
  EXPECT_EQ(call("POST", "/api/v1/maps/nope/scans", "{}").status, 404);
  EXPECT_EQ(call("GET", "/api/v1/maps/nope").status, 404);
  EXPECT_EQ(call("GET", "/api/v1/maps/Bad").status, 400);
  for (const std::string server_wide : {"/api/v1/maps/a/maps", "/api/v1/maps/a/network", "/api/v1/maps/a/foxglove",
                                        "/api/v1/maps/a/", "/api/v1/maps/a/web/index.html", "/api/v1/maps/a/x"})
    EXPECT_EQ(call("GET", server_wide).status, 404) << server_wide;
  EXPECT_EQ(call("GET", "/api/v1/maps/a/events").status, 426);  // a map's WebSocket, asked for without an upgrade
  const auto wrong_method = call("DELETE", "/api/v1/maps/a/scans");
  EXPECT_EQ(wrong_method.status, 405);
  EXPECT_EQ(json::parse(wrong_method.body)["detail"], "allowed: POST");
  EXPECT_EQ(call("DELETE", "/api/v1/maps/default").status, 409);
  EXPECT_EQ(call("DELETE", "/api/v1/maps/Bad").status, 400);
  // A bad body to a map's route is that route's 400, and leaves the map as it was.
  EXPECT_EQ(call("POST", "/api/v1/maps/a/primitives", R"({"segments": [{"p0": [0, "x"], "p1": [1, 1]}]})").status, 400);
  EXPECT_TRUE(get_json("/api/v1/maps/a/elements")["elements"].empty());
  EXPECT_EQ(map_ids(get_json("/api/v1/maps")), (std::set<std::string>{"a", "default"}));
  EXPECT_EQ(files_before(), before);
}

class MapsTokenTest : public MapsTest {
 protected:
  void SetUp() override {
    extra_args_ = {"--token", "s3cret"};
    MapsTest::SetUp();
  }
};

TEST_F(MapsTokenTest, MakingAndDeletingMapsAndWritingToThemNeedTheToken) {
  EXPECT_EQ(call("POST", "/api/v1/maps", json{{"id", "b"}}.dump()).status, 401);
  EXPECT_FALSE(std::filesystem::exists(maps_dir() / "b.db"));
  EXPECT_EQ(client_->request("POST", "/api/v1/maps", json{{"id", "b"}}.dump(), "application/json", "s3cret").status,
            201);
  EXPECT_EQ(call("POST", "/api/v1/maps/b/primitives", json{{"segments", {segment(0, 0, 1, 0)}}}.dump()).status, 401);
  EXPECT_EQ(call("DELETE", "/api/v1/maps/b").status, 401);
  EXPECT_EQ(call("GET", "/api/v1/maps/b/map").status, 200);  // reads need no token
  EXPECT_EQ(client_->request("DELETE", "/api/v1/maps/b", "", "application/json", "s3cret").status, 200);
}

// wmd on a private copy of the shipped rules: a map's own rule files go in rules/maps/<id>/.
class MapsOwnRulesTest : public MapsTest {
 protected:
  void SetUp() override {
    use_rules_copy();
    MapsTest::SetUp();
  }

  // Waits until `target` (a rules status) reaches `generation`; the status then.
  json rules_at(const std::string& target, int generation) {
    json rules;
    for (int i = 0; i < 300; ++i) {
      rules = get_json(target);
      if (rules["generation"].get<int>() >= generation) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return rules;
  }

  // The rule that decided a view of 2 m of the plan's solid wall from `x`: each call a stretch of its own, as a view of
  // a stretch that an earlier view added as an element would match that element.
  std::string wall_rule(const std::string& map_prefix, double x) {
    const json answer = send_json("POST", map_prefix + "/primitives",
                                  {{"source", "robot-7"}, {"segments", {segment(x, 10.004, x + 2, 9.998)}}});
    return answer["decisions"].at(0)["rule"].get<std::string>();
  }
};

// Each map takes the shared rules and its own files beside them, followed live; no other map sees them.
TEST_F(MapsOwnRulesTest, AMapsOwnRuleFilesDecideOnThatMapOnlyAndAreFollowedLive) {
  send_json("POST", "/api/v1/maps", {{"id", "floor2"}}, 201);
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  send_json("PUT", "/api/v1/maps/floor2/floorplan", lab_plan());
  EXPECT_EQ(wall_rule("/api/v1/maps/floor2", 0.5), "solid_confirmed");

  const auto own = dir_.path() / "rules" / "maps" / "floor2";
  std::filesystem::create_directories(own);
  std::ofstream(own / "50_floor2.pl")
      << "override(observation(_, _, _, _), element(_, O, _), add, floor2_no_walls, \"floor 2 confirms nothing\") "
         ":-\n    attribute(O, solid).\n";
  const json floor2 = rules_at("/api/v1/maps/floor2/rules", 2);
  ASSERT_EQ(floor2["generation"], 2) << floor2.dump();
  ASSERT_EQ(floor2["files"].size(), 2u) << floor2.dump();
  EXPECT_EQ(wall_rule("/api/v1/maps/floor2", 5), "floor2_no_walls");
  EXPECT_EQ(wall_rule("/api/v1", 5), "solid_confirmed");
  EXPECT_EQ(get_json("/api/v1/rules")["files"].size(), 1u);

  // A broken edit of the map's file is refused with its path; the map's previous rules stay.
  std::ofstream(own / "50_floor2.pl") << "override(broken :-\n";
  json refused;
  for (int i = 0; i < 300; ++i) {
    refused = get_json("/api/v1/maps/floor2/rules");
    if (!refused["last_error"].get<std::string>().empty()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_NE(refused["last_error"].get<std::string>().find("50_floor2.pl"), std::string::npos) << refused.dump();
  EXPECT_EQ(refused["generation"], 2);
  EXPECT_EQ(wall_rule("/api/v1/maps/floor2", 10), "floor2_no_walls");

  // Still the map's after a restart; and the default map has a directory of its own too.
  std::filesystem::remove(own / "50_floor2.pl");
  std::filesystem::create_directories(dir_.path() / "rules" / "maps" / "default");
  std::ofstream(dir_.path() / "rules" / "maps" / "default" / "50_default.pl")
      << "override(observation(_, _, _, _), element(_, O, _), add, default_no_walls, \"default\") "
         ":-\n    attribute(O, solid).\n";
  restart();
  EXPECT_EQ(wall_rule("/api/v1/maps/floor2", 15), "solid_confirmed");
  EXPECT_EQ(wall_rule("/api/v1", 10), "default_no_walls");
}

// A robot that takes the lift: heard on one floor, then on the next. The server-wide list shows it once, on the map
// that heard from it last; each map keeps its own track of it.
TEST_F(MapsTest, ARobotBelongsToTheMapThatHeardFromItLast) {
  send_json("POST", "/api/v1/maps", {{"id", "floor2"}}, 201);
  send_json("POST", "/api/v1/primitives", {{"source", "lifty"}, {"segments", {segment(0, 0, 0, 4)}}});
  send_json("POST", "/api/v1/primitives", {{"source", "stays"}, {"segments", {segment(5, 0, 5, 4)}}});
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // last_seen is the wall clock
  send_json("POST", "/api/v1/maps/floor2/primitives", {{"source", "lifty"}, {"segments", {segment(0, 0, 3, 0)}}});

  const json all = get_json("/api/v1/robots")["robots"];
  ASSERT_EQ(all.size(), 2u) << all.dump();
  EXPECT_EQ(all[0]["id"], "lifty");
  EXPECT_EQ(all[0]["map"], "floor2");
  EXPECT_EQ(all[0]["maps"], json({"default", "floor2"}));
  EXPECT_EQ(all[1]["id"], "stays");
  EXPECT_EQ(all[1]["map"], "default");
  const json ground = get_json("/api/v1/maps/default/robots")["robots"];
  ASSERT_EQ(ground.size(), 2u);
  EXPECT_EQ(ground[0]["map"], "default");
  const json upstairs = get_json("/api/v1/maps/floor2/robots")["robots"];
  ASSERT_EQ(upstairs.size(), 1u);
  EXPECT_EQ(upstairs[0]["id"], "lifty");
  EXPECT_EQ(upstairs[0]["primitives"], 1);
}

// One map's writer held up (another connection holds its SQLite file's write lock) does not hold up another
// map: its scans are answered meanwhile, and the held map's request completes once the lock goes.
TEST_F(MapsTest, AMapWhoseWriterIsHeldDoesNotHoldUpAnother) {
  send_json("POST", "/api/v1/maps", {{"id", "held"}}, 201);
  send_json("POST", "/api/v1/maps", {{"id", "free"}}, 201);
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((maps_dir() / "held.db").string().c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr), SQLITE_OK);
  auto held = std::async(std::launch::async, [&] {
    client::HttpClient client(server_->url());
    return client.request("POST", "/api/v1/maps/held/primitives",
                          json{{"source", "r1"}, {"segments", {segment(0, 0, 0, 4)}}}.dump());
  });
  // The free map's answers while the held map's request waits (its store retries the lock for 5 s).
  std::size_t answered = 0;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  for (int i = 0; i < 200 && std::chrono::steady_clock::now() < until; ++i) {
    const auto r = call("POST", "/api/v1/maps/free/primitives",
                        json{{"source", "r2"}, {"segments", {segment(i, 0, i, 3)}}}.dump());
    ASSERT_EQ(r.status, 200) << r.body;
    ++answered;
  }
  EXPECT_EQ(held.wait_for(std::chrono::seconds(0)), std::future_status::timeout) << "the held map answered";
  EXPECT_GE(answered, 20u);
  ASSERT_EQ(sqlite3_exec(db, "COMMIT", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  const auto r = held.get();
  EXPECT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(get_json("/api/v1/maps/held/elements")["elements"].size(), 1u);
  EXPECT_EQ(get_json("/api/v1/maps/free/robots")["robots"][0]["primitives"], static_cast<int>(answered));
}

// Each map's live events are its own: a change on one map reaches the WebSocket of that map only, and a client
// following a map that is deleted is told so.
TEST_F(MapsTest, EachMapHasItsOwnEventsAndTheirClientsHearOfItsDeletion) {
  send_json("POST", "/api/v1/maps", {{"id", "floor2"}}, 201);
  EventClient floor2(server_->port(), "/api/v1/maps/floor2/events");
  EventClient ground(server_->port());
  EXPECT_EQ(floor2.next()["type"], "hello");
  EXPECT_EQ(ground.next()["type"], "hello");
  send_json("POST", "/api/v1/maps/floor2/primitives", {{"source", "r2"}, {"segments", {segment(0, 0, 0, 4)}}});
  send_json("POST", "/api/v1/primitives", {{"source", "r1"}, {"segments", {segment(7, 0, 7, 5)}}});
  const json upstairs = floor2.next_of("update");
  ASSERT_EQ(upstairs["decisions"].size(), 1u) << upstairs.dump();
  EXPECT_EQ(upstairs["decisions"][0]["observer"], "r2");
  const json downstairs = ground.next_of("update");
  ASSERT_EQ(downstairs["decisions"].size(), 1u) << downstairs.dump();
  EXPECT_EQ(downstairs["decisions"][0]["observer"], "r1");

  send_json("DELETE", "/api/v1/maps/floor2", json(nullptr));
  EXPECT_EQ(floor2.next_of("map_removed")["map"], "floor2");
  // No stream for a map there is not, or an id that is none.
  const auto upgrade = [&](const std::string& target) {
    return raw_request(server_->port(), boost::beast::http::verb::get, target,
                       {{"Host", "127.0.0.1"},
                        {"Upgrade", "websocket"},
                        {"Connection", "Upgrade"},
                        {"Sec-WebSocket-Version", "13"},
                        {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="}});
  };
  const auto refused = upgrade("/api/v1/maps/floor2/events");
  EXPECT_EQ(refused.result_int(), 404u) << refused.body();
  const auto bad = upgrade("/api/v1/maps/Bad/events");
  EXPECT_EQ(bad.result_int(), 400u) << bad.body();
}

// The RMF office as a building of two floors: its level L1 as drawn, and a level L2 3.5 m above it with the same
// walls and doors and no furniture (the structure of a real multi-level building.yaml: one "levels" map, each level
// with its own vertices, walls, doors, models, measurements and elevation).
std::string two_level_office() {
  const std::string office = slurp(real_data("rmf-office/office.building.yaml", "plans/rmf-office.building.yaml"));
  const auto l1 = office.find("\n  L1:\n"), lifts = office.find("\nlifts:");
  EXPECT_NE(l1, std::string::npos);
  EXPECT_NE(lifts, std::string::npos);
  std::string l2 = office.substr(l1, lifts - l1);
  l2.replace(l2.find("\n  L1:\n"), 7, "\n  L2:\n");
  l2.replace(l2.find("    elevation: 0"), 16, "    elevation: 3.5");
  const auto models = l2.find("\n    models:"), vertices = l2.find("\n    vertices:");
  EXPECT_LT(models, vertices);
  l2.erase(models, vertices - models);
  return office.substr(0, lifts) + l2 + office.substr(lifts);
}

TEST_F(MapsTest, ABuildingOfSeveralLevelsImportsAsAMapPerLevel) {
  const auto building = two_level_office();
  auto r = call("POST", "/api/v1/maps?prefix=office", building, "application/yaml");
  ASSERT_EQ(r.status, 201) << r.body;
  const json made = json::parse(r.body)["maps"];
  ASSERT_EQ(made.size(), 2u);
  EXPECT_EQ(made[0]["id"], "office-l1");
  EXPECT_EQ(made[0]["level"], "L1");
  EXPECT_EQ(made[1]["id"], "office-l2");
  // The same level imported alone, as PUT /api/v1/floorplan?level= does, is what the level's map holds.
  send_json("POST", "/api/v1/maps", {{"id", "alone"}}, 201);
  r = call("PUT", "/api/v1/maps/alone/floorplan?level=L1", building, "application/yaml");
  ASSERT_EQ(r.status, 200) << r.body;
  const json l1 = get_json("/api/v1/maps/office-l1/floorplan"), alone = get_json("/api/v1/maps/alone/floorplan");
  EXPECT_EQ(l1["objects"], alone["objects"]);
  const json l2 = get_json("/api/v1/maps/office-l2/floorplan");
  std::size_t furniture = 0, walls_l1 = 0, walls_l2 = 0;
  for (const auto& o : l1["objects"]) {
    furniture += o["kind"] == "furniture";
    walls_l1 += o["kind"] == "wall";
  }
  for (const auto& o : l2["objects"]) {
    EXPECT_NE(o["kind"], "furniture");
    walls_l2 += o["kind"] == "wall";
  }
  EXPECT_GT(furniture, 0u);
  EXPECT_GT(walls_l1, 20u);
  EXPECT_EQ(walls_l1, walls_l2);
  EXPECT_EQ(made[1]["objects"], l2["objects"].size());

  // All or nothing: a second import under the same prefix is refused whole, and a broken level makes no map.
  r = call("POST", "/api/v1/maps?prefix=office", building, "application/yaml");
  EXPECT_EQ(r.status, 409) << r.body;
  std::string broken = building;
  broken.replace(broken.rfind("    measurements:"), 17, "    measurementz:");  // L2 loses its scale
  r = call("POST", "/api/v1/maps?prefix=other", broken, "application/yaml");
  EXPECT_EQ(r.status, 400) << r.body;
  for (const auto& [body, query] :
       std::vector<std::pair<std::string, std::string>>{{building, ""},
                                                        {building, "?prefix=Bad"},
                                                        {"levels: {}", "?prefix=x"},
                                                        {"{{{", "?prefix=x"},
                                                        {std::string("levels:\n  L\xff: {}\n"), "?prefix=x"}}) {
    r = call("POST", "/api/v1/maps" + query, body, "application/yaml");
    EXPECT_EQ(r.status, 400) << query << " " << r.body;
  }
  EXPECT_EQ(map_ids(get_json("/api/v1/maps")), (std::set<std::string>{"alone", "default", "office-l1", "office-l2"}));
}

// A map deleted while a robot posts to it: every scan is answered 200 (it came before the delete, and is in the map
// that goes) or 404 map_not_found (after), never anything else, in that order; the map's files go, and the same id
// made again is an empty map.
TEST_F(MapsTest, AMapDeletedDuringAReplayAnswersEachScanWholeOrNotFound) {
  send_json("POST", "/api/v1/maps", {{"id", "doomed"}}, 201);
  const auto log = real_data("carmen/intel-corrected.log.gz", "carmen/intel-corrected.log.gz");
  logs::CarmenLogReader reader(log);
  std::vector<std::string> bodies;
  while (auto scan = reader.next()) {
    bodies.push_back(logs::laser_scan_body(scan->scan, "intel", scan->timestamp_s).dump());
    if (bodies.size() == 300) break;
  }
  std::atomic<std::size_t> accepted{0};
  auto replay = std::async(std::launch::async, [&] {
    client::HttpClient client(server_->url());
    std::vector<int> statuses;
    for (const auto& body : bodies) {
      const auto r = client.request("POST", "/api/v1/maps/doomed/scans", body);
      statuses.push_back(r.status);
      if (r.status == 200) ++accepted;
      if (r.status != 200) {
        EXPECT_EQ(json::parse(r.body)["error"], "map_not_found") << r.body;
      }
    }
    return statuses;
  });
  while (accepted < 50) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  send_json("DELETE", "/api/v1/maps/doomed", json(nullptr));
  const auto statuses = replay.get();
  const auto first_refused = std::find(statuses.begin(), statuses.end(), 404);
  ASSERT_NE(first_refused, statuses.end()) << "the delete came after the whole replay";
  EXPECT_GE(first_refused - statuses.begin(), 50);
  EXPECT_TRUE(std::all_of(statuses.begin(), first_refused, [](int s) { return s == 200; }));
  EXPECT_TRUE(std::all_of(first_refused, statuses.end(), [](int s) { return s == 404; }));
  // Its files are gone once the last request let go of it (the test's requests have all ended).
  const auto left = [&] {
    std::size_t n = 0;
    for (const auto& entry : std::filesystem::directory_iterator(maps_dir()))
      n += entry.path().filename().string().find("doomed") != std::string::npos;
    return n;
  };
  for (int i = 0; i < 100 && left() > 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(left(), 0u);
  send_json("POST", "/api/v1/maps", {{"id", "doomed"}}, 201);
  EXPECT_TRUE(get_json("/api/v1/maps/doomed/elements")["elements"].empty());
  EXPECT_TRUE(get_json("/api/v1/maps/doomed/robots")["robots"].empty());
}

// wmctl --map sends every map command to that map; `wmctl maps` lists, makes and deletes them.
// Two buildings of one site, the real AMRL plans of GDC1 and AHG2, as two maps: each holds its own plan, the same
// objects as that plan loaded alone into the default map, and the other's routes do not see it.
TEST_F(MapsTest, ASiteHoldsGDC1AndAHG2AsTwoMaps) {
  const auto wmctl_at = [&](const std::string& args) { return run_command(wmctl(server_->url(), args)); };
  const auto gdc1 = real_data("amrl-vectormaps/GDC1.vectormap.json", "plans/GDC1.vectormap.json");
  const auto ahg2 = real_data("amrl-vectormaps/AHG2.vectormap.json", "plans/AHG2.vectormap.json");
  for (const auto& [id, plan] : {std::pair{"gdc1", gdc1}, std::pair{"ahg2", ahg2}}) {
    ASSERT_EQ(wmctl_at(std::string("maps create ") + id).status, 0);
    const auto r = wmctl_at(std::string("--map ") + id + " floorplan load " + plan.string());
    ASSERT_EQ(r.status, 0) << r.output;
  }
  const json on_gdc1 = get_json("/api/v1/maps/gdc1/floorplan"), on_ahg2 = get_json("/api/v1/maps/ahg2/floorplan");
  EXPECT_GT(on_gdc1["objects"].size(), 100u);
  EXPECT_GT(on_ahg2["objects"].size(), 100u);
  EXPECT_NE(on_gdc1["objects"], on_ahg2["objects"]);
  EXPECT_TRUE(get_json("/api/v1/floorplan")["objects"].empty());
  // Each as the same plan loaded alone.
  for (const auto& [id, plan] : {std::pair{"gdc1", gdc1}, std::pair{"ahg2", ahg2}}) {
    ASSERT_EQ(wmctl_at("floorplan load " + plan.string()).status, 0);
    EXPECT_EQ(get_json("/api/v1/floorplan")["objects"],
              get_json(std::string("/api/v1/maps/") + id + "/floorplan")["objects"])
        << id;
  }
  const json list = get_json("/api/v1/maps");
  ASSERT_EQ(list["maps"].size(), 3u);
  EXPECT_EQ(list["maps"][1]["id"], "ahg2");
  EXPECT_EQ(list["maps"][1]["objects"], on_ahg2["objects"].size());
  EXPECT_EQ(list["maps"][2]["id"], "gdc1");
  EXPECT_EQ(list["maps"][2]["objects"], on_gdc1["objects"].size());
}

TEST_F(MapsTest, WmctlWorksOnTheMapItIsGiven) {
  const auto wmctl_at = [&](const std::string& args) { return run_command(wmctl(server_->url(), args)); };
  auto r = wmctl_at("maps create lift-b");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto plan = dir_.path() / "plan.json";
  std::ofstream(plan) << json(lab_plan()).dump();
  r = wmctl_at("--map lift-b floorplan load " + plan.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(get_json("/api/v1/maps/lift-b/floorplan")["objects"].size(), 2u);
  EXPECT_TRUE(get_json("/api/v1/floorplan")["objects"].empty());
  r = wmctl_at("--json --map lift-b health");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(json::parse(r.output.substr(r.output.find('{')))["objects"], 2);
  r = wmctl_at("maps");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("lift-b: plan 'lab-e2e', 2 objects"), std::string::npos) << r.output;
  EXPECT_EQ(wmctl_at("--map Nope map").status, 2);  // not an id: refused before any request
  EXPECT_EQ(wmctl_at("--map nope map").status, 1);  // no such map: the server's 404
  const auto building = dir_.path() / "office.building.yaml";
  std::ofstream(building) << two_level_office();
  r = wmctl_at("maps import " + building.string() + " --prefix hq");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("created map hq-l2 (level L2"), std::string::npos) << r.output;
  EXPECT_EQ(wmctl_at("maps import " + building.string()).status, 2);  // --prefix is required
  r = wmctl_at("maps delete lift-b");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(map_ids(get_json("/api/v1/maps")), (std::set<std::string>{"default", "hq-l1", "hq-l2"}));
}

// What a replay left in a map, comparable between maps: its elements and its decisions (without the map's name).
struct MapContent {
  json elements;
  std::vector<json> decisions;
};

class MapsReplayTest : public MapsTest {
 protected:
  void SetUp() override {
    extra_args_ = {"--sync", "normal"};
    MapsTest::SetUp();
  }

  // The Intel log's first scans, with wmctl replay --map (sequential, as a robot posts).
  void replay_intel(const std::string& map) {
    const auto log = real_data("carmen/intel-corrected.log.gz", "carmen/intel-corrected.log.gz");
    const auto r = run_command(
        wmctl(server_->url(), "--map " + map + " --json replay " + log.string() + " --limit 300 --source intel"));
    ASSERT_EQ(r.status, 0) << r.output;
  }

  // A drive through GDC1 ray-cast from its plan, posted one scan at a time.
  void replay_gdc1(const std::string& map) {
    const auto lines =
        raycast::read_vectormap(real_data("amrl-vectormaps/GDC1.vectormap.json", "plans/GDC1.vectormap.json").string());
    raycast::DriveOptions drive;
    drive.step_m = 0.6;
    const auto scans = raycast::simulate_scans(lines, raycast::gdc1_route(), drive);
    ASSERT_GT(scans.size(), 100u);
    client::HttpClient client(server_->url());
    double stamp = 0;
    for (const auto& scan : scans) {
      auto body = logs::laser_scan_body(scan, "gdc1-robot", stamp += 0.5);
      body["pose_cov"] = {{1e-4, 0, 0}, {0, 1e-4, 0}, {0, 0, 1.2e-5}};
      const auto r = client.request("POST", "/api/v1/maps/" + map + "/scans", body.dump());
      ASSERT_EQ(r.status, 200) << r.body;
    }
  }

  MapContent content(const std::string& map) {
    MapContent c;
    c.elements = get_json("/api/v1/maps/" + map + "/elements")["elements"];
    std::int64_t since = 0;
    for (;;) {
      const json page = get_json("/api/v1/maps/" + map + "/decisions?since=" + std::to_string(since) + "&limit=1000");
      if (page["decisions"].empty()) break;
      for (auto d : page["decisions"]) {
        since = d["seq"].get<std::int64_t>();
        c.decisions.push_back(std::move(d));
      }
    }
    return c;
  }
};

void expect_same(const MapContent& a, const MapContent& b, const std::string& what) {
  std::printf("%s: %zu elements, %zu decisions\n", what.c_str(), a.elements.size(), a.decisions.size());
  EXPECT_GT(a.elements.size(), 20u) << what;
  EXPECT_EQ(a.elements, b.elements) << what;
  ASSERT_EQ(a.decisions.size(), b.decisions.size()) << what;
  for (std::size_t i = 0; i < a.decisions.size(); ++i) ASSERT_EQ(a.decisions[i], b.decisions[i]) << what << " #" << i;
}

TEST_F(MapsReplayTest, TwoMapsReplayedAtOnceEachEqualTheSameReplayAloneAndSurviveARestartAndADelete) {
  for (const auto* id : {"intel", "gdc1", "intel-alone", "gdc1-alone"})
    send_json("POST", "/api/v1/maps", {{"id", id}}, 201);
  {
    auto intel = std::async(std::launch::async, [&] { replay_intel("intel"); });
    auto gdc1 = std::async(std::launch::async, [&] { replay_gdc1("gdc1"); });
    intel.get();
    gdc1.get();
  }
  replay_intel("intel-alone");
  replay_gdc1("gdc1-alone");
  const auto intel = content("intel"), gdc1 = content("gdc1");
  expect_same(intel, content("intel-alone"), "intel");
  expect_same(gdc1, content("gdc1-alone"), "gdc1");
  // Nothing of one drive in the other's map, nor in the default map.
  EXPECT_TRUE(get_json("/api/v1/elements")["elements"].empty());
  EXPECT_EQ(get_json("/api/v1/maps/intel/robots")["robots"].size(), 1u);
  EXPECT_EQ(get_json("/api/v1/maps/intel/robots")["robots"][0]["id"], "intel");

  restart();
  expect_same(content("intel"), intel, "intel after a restart");
  expect_same(content("gdc1"), gdc1, "gdc1 after a restart");

  send_json("DELETE", "/api/v1/maps/intel", json(nullptr));
  expect_same(content("gdc1"), gdc1, "gdc1 after intel was deleted");
  EXPECT_EQ(call("GET", "/api/v1/maps/intel/elements").status, 404);
}

}  // namespace
}  // namespace wm::testing
