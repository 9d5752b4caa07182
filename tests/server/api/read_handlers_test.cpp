// The handlers that read: each route's success and its documented refusals, through the router, against a fake
// of the service port.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "server/api/handlers.h"
#include "server/storage/database.h"
#include "tests/server/api/api_test_helpers.h"
#include "tests/support/temp_dir.h"

namespace wm::testing {
namespace {

using http::verb;

class ReadHandlersTest : public ApiTest {
 protected:
  void SetUp() override { load_demo_plan(); }

  void add_element(std::int64_t number, std::int64_t support) {
    world::Element e;
    e.number = number;
    e.segment = fusion::LineSegment::from_points({1, 2}, {4, 2}, Eigen::Matrix2d::Identity() * 1e-4);
    e.support = support;
    e.origin = "client";
    e.observer = "robot-1";
    world_.state().elements.put(e);
  }

  /// A grid with one laser scan in it.
  void fill_grid() {
    world_.grid.emplace(fusion::GridOptions{});
    fusion::LaserScan scan;
    scan.sensor_pose = {0, 0, 0};
    scan.angle_min_rad = -0.5;
    scan.angle_increment_rad = 0.01;
    scan.ranges_m.assign(101, 2.0);
    scan.range_min_m = 0.05;
    scan.range_max_m = 8.0;
    world_.grid->insert(scan);
  }
};

TEST_F(ReadHandlersTest, HealthSaysOkWithTheMapsCounts) {
  const auto response = send(verb::get, "/api/v1/health");
  ASSERT_EQ(status_of(response), 200);
  const auto body = json_of(response);
  EXPECT_EQ(body["status"], "ok");
  EXPECT_EQ(body["plan"], "lab");
  EXPECT_EQ(body["objects"], 2);
  EXPECT_EQ(body["rules"]["files"][0]["path"], "prolog/world_model.pl");
  EXPECT_EQ(response[http::field::content_type], "application/json");
}

TEST_F(ReadHandlersTest, HealthCountsWhatTheServerReportedAndListsTheLastReports) {
  EXPECT_FALSE(json_of(send(verb::get, "/api/v1/health")).contains("diagnostics"));  // no sink wired
  common::Diagnostics diagnostics("", nullptr, 2);
  diagnostics_ = &diagnostics;
  auto body = json_of(send(verb::get, "/api/v1/health"));
  EXPECT_EQ(body["diagnostics"]["warnings"], 0);
  EXPECT_EQ(body["diagnostics"]["errors"], 0);
  EXPECT_TRUE(body["diagnostics"]["recent"].empty());

  diagnostics.report(common::Severity::warning, "grid", "grid flush failed");
  diagnostics.report(common::Severity::info, "rules", "rules reloaded");
  diagnostics.report(common::Severity::error, "grid", "scan 7 not inserted into the grid");
  diagnostics.report(common::Severity::warning, "foxglove", "foxglove: grid not sent");
  body = json_of(send(verb::get, "/api/v1/health"));
  ASSERT_EQ(body["status"], "ok");
  const auto& d = body["diagnostics"];
  EXPECT_EQ(d["warnings"], 2);
  EXPECT_EQ(d["errors"], 1);
  EXPECT_EQ(d["info"], 1);
  EXPECT_EQ(d["by_where"]["grid"]["warnings"], 1);
  EXPECT_EQ(d["by_where"]["grid"]["errors"], 1);
  EXPECT_EQ(d["by_where"]["foxglove"]["warnings"], 1);
  // Only the last two are kept, oldest first.
  ASSERT_EQ(d["recent"].size(), 2u);
  EXPECT_EQ(d["recent"][0]["where"], "grid");
  EXPECT_EQ(d["recent"][0]["severity"], "error");
  EXPECT_EQ(d["recent"][0]["message"], "scan 7 not inserted into the grid");
  EXPECT_EQ(d["recent"][1]["where"], "foxglove");
  EXPECT_EQ(d["recent"][1]["severity"], "warning");
  EXPECT_GT(d["recent"][1]["at"].get<double>(), 1.6e9);  // seconds since the Unix epoch
}

TEST_F(ReadHandlersTest, RootIsTheIndexWithoutAViewerAndTheViewerWithOne) {
  EXPECT_EQ(json_of(send(verb::get, "/"))["api"], "/api/v1");
  TempDir dir;
  std::ofstream(dir.path() / "index.html") << "<title>viewer</title>";
  options_.web_dir = dir.path().string();
  const auto response = send(verb::get, "/");
  EXPECT_EQ(status_of(response), 200);
  EXPECT_EQ(response.body(), "<title>viewer</title>");
  EXPECT_EQ(response[http::field::content_type], "text/html; charset=utf-8");
}

TEST_F(ReadHandlersTest, StaticFilesAreServedFromTheViewerDirectoryOnly) {
  EXPECT_EQ(status_of(send(verb::get, "/web/app.js")), 404);  // no --web
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "web" / "lib");
  std::ofstream(dir.path() / "web" / "lib" / "app.js") << "export const x = 1;";
  std::ofstream(dir.path() / "web" / ".secret") << "token";
  std::ofstream(dir.path() / "outside.txt") << "no";
  options_.web_dir = (dir.path() / "web").string();
  const auto response = send(verb::get, "/web/lib/app.js");
  ASSERT_EQ(status_of(response), 200);
  EXPECT_EQ(response.body(), "export const x = 1;");
  EXPECT_EQ(response[http::field::content_type], "text/javascript; charset=utf-8");
  for (const std::string target : {"/web/../outside.txt", "/web/%2e%2e/outside.txt", "/web/.secret", "/web/missing.js",
                                   "/web/", "/web//etc/passwd"})
    EXPECT_EQ(status_of(send(verb::get, target)), 404) << target;
  EXPECT_EQ(status_of(send(verb::post, "/web/lib/app.js", "{}")), 405);
}

TEST_F(ReadHandlersTest, MapBboxKeepsWhatCrossesTheBoxAndRefusesABadBox) {
  add_element(1, 1);  // (1, 2) – (4, 2); the plan: wall-n (0, 10) – (20, 10), table-1 about (5, 5)
  const auto ids = [](const nlohmann::json& body, const char* key) {
    std::vector<std::string> v;
    for (const auto& item : body[key]) v.push_back(item["id"]);
    return v;
  };
  auto body = json_of(send(verb::get, "/api/v1/map?bbox=19,9.5,30,10.5"));
  EXPECT_EQ(ids(body, "objects"), std::vector<std::string>{"wall-n"});
  EXPECT_TRUE(body["elements"].empty());
  EXPECT_EQ(body["bbox"], nlohmann::json::array({19, 9.5, 30, 10.5}));
  body = json_of(send(verb::get, "/api/v1/map?bbox=3.5,1.9,3.6,2.1"));
  EXPECT_TRUE(body["objects"].empty());
  EXPECT_EQ(ids(body, "elements"), std::vector<std::string>{"e1"});
  // Inside the table, clear of its edges: nothing crosses the box. Over its edge: the whole table.
  body = json_of(send(verb::get, "/api/v1/map?bbox=4.9,4.9,5.1,5.1"));
  EXPECT_TRUE(body["objects"].empty());
  body = json_of(send(verb::get, "/api/v1/map?bbox=4.5,4.5,5.5,5.5"));
  ASSERT_EQ(ids(body, "objects"), std::vector<std::string>{"table-1"});
  // The box's corner just misses the element's end: (0.9, 1.9) – (0.99, 1.99) against (1, 2).
  EXPECT_TRUE(json_of(send(verb::get, "/api/v1/map?bbox=0.9,1.9,0.99,1.99"))["elements"].empty());
  const auto geojson = json_of(send(verb::get, "/api/v1/map?format=geojson&bbox=3.5,1.9,3.6,2.1"));
  ASSERT_EQ(geojson["features"].size(), 1u);
  for (const std::string bad : {"1,2,3", "1,2,3,x", "3,0,1,1", "0,0,1,nan", "0,0,1,1,2", "0,0,1e7,1"}) {
    const auto response = send(verb::get, "/api/v1/map?bbox=" + bad);
    EXPECT_EQ(status_of(response), 400) << bad;
    EXPECT_NE(response.body().find("bbox"), std::string::npos) << bad;
  }
}

TEST_F(ReadHandlersTest, FloorPlanIsTheLoadedPlanInCanonicalJson) {
  const auto response = send(verb::get, "/api/v1/floorplan");
  ASSERT_EQ(status_of(response), 200);
  const auto body = json_of(response);
  EXPECT_EQ(body["name"], "lab");
  EXPECT_EQ(body["objects"].size(), 2u);
}

TEST_F(ReadHandlersTest, MapComesAsJsonDxfOrGeoJsonAndRefusesOtherFormats) {
  add_element(1, 1);
  auto response = send(verb::get, "/api/v1/map");
  ASSERT_EQ(status_of(response), 200);
  EXPECT_EQ(json_of(response)["elements"].size(), 1u);
  response = send(verb::get, "/api/v1/map?format=dxf");
  ASSERT_EQ(status_of(response), 200);
  EXPECT_EQ(response[http::field::content_type], "image/vnd.dxf");
  EXPECT_NE(response.body().find("plan_unobserved"), std::string::npos);
  response = send(verb::get, "/api/v1/map?format=geojson");
  ASSERT_EQ(status_of(response), 200);
  EXPECT_EQ(json_of(response)["type"], "FeatureCollection");
  response = send(verb::get, "/api/v1/map?format=svg");
  EXPECT_EQ(status_of(response), 400);
  EXPECT_NE(response.body().find("format"), std::string::npos);
}

TEST_F(ReadHandlersTest, AsBuiltReportSaysWhatMovedAndByHowMuch) {
  auto table = world_.state().objects[1];
  table.adjustments = 1;
  table.body = fusion::RigidObject({5.3, 5.4, 0.4}, table.body.pose_cov(), table.plan->edges());
  world_.state().objects.put(1, table);
  auto wall = world_.state().objects[0];
  wall.confirmations = 2;
  world_.state().objects.put(0, wall);
  add_element(3, 2);
  const auto response = send(verb::get, "/api/v1/report/as-built");
  ASSERT_EQ(status_of(response), 200);
  const auto body = json_of(response);
  EXPECT_EQ(body["summary"]["moved"], 1);
  EXPECT_EQ(body["summary"]["confirmed"], 1);
  EXPECT_EQ(body["summary"]["not_in_plan"], 1);
  EXPECT_EQ(body["objects"][0]["status"], "confirmed");
  EXPECT_FALSE(body["objects"][0].contains("moved_by"));
  const auto& moved = body["objects"][1]["moved_by"];
  EXPECT_NEAR(moved["dx"].get<double>(), 0.3, 1e-12);
  EXPECT_NEAR(moved["dy"].get<double>(), 0.4, 1e-12);
  EXPECT_NEAR(moved["distance"].get<double>(), 0.5, 1e-12);
  EXPECT_NEAR(moved["dtheta"].get<double>(), 0.1, 1e-12);
  EXPECT_EQ(body["not_in_plan"][0]["id"], "e3");
}

TEST_F(ReadHandlersTest, ObjectsAndElementsOneByOneOr404) {
  add_element(1, 1);
  EXPECT_EQ(json_of(send(verb::get, "/api/v1/objects"))["objects"].size(), 2u);
  EXPECT_EQ(json_of(send(verb::get, "/api/v1/objects/table-1"))["edges"].size(), 4u);
  EXPECT_EQ(json_of(send(verb::get, "/api/v1/elements"))["elements"].size(), 1u);
  EXPECT_EQ(json_of(send(verb::get, "/api/v1/elements/e1"))["id"], "e1");
  for (const std::string target : {"/api/v1/objects/chair", "/api/v1/elements/e9", "/api/v1/elements/x"}) {
    const auto response = send(verb::get, target);
    EXPECT_EQ(status_of(response), 404) << target;
    EXPECT_EQ(error_of(response), "not_found");
  }
}

TEST_F(ReadHandlersTest, HistoriesListTheDecisionsAboutAnObjectOrElementOr404) {
  auto d = FakeWorldPort::decision(rules::Action::confirm, "table-1/2");
  d.object = "table-1";
  world_.logged = {d};
  auto body = json_of(send(verb::get, "/api/v1/objects/table-1/history"));
  EXPECT_EQ(body["exists"], true);
  EXPECT_EQ(body["decisions"][0]["action"], "delete");
  // An edge id has a slash; its element history is every decision about it.
  body = json_of(send(verb::get, "/api/v1/elements/table-1/2/history"));
  EXPECT_EQ(body["id"], "table-1/2");
  EXPECT_EQ(body["exists"], false);
  EXPECT_EQ(body["decisions"].size(), 1u);
  EXPECT_EQ(status_of(send(verb::get, "/api/v1/elements/e5/history")), 404);
  EXPECT_EQ(status_of(send(verb::get, "/api/v1/objects/chair/history")), 404);
}

TEST_F(ReadHandlersTest, DecisionsArePagedBySequenceAndCheckTheirParameters) {
  for (int i = 1; i <= 3; ++i) {
    auto d = FakeWorldPort::decision(rules::Action::add, "e" + std::to_string(i));
    d.seq = i;
    world_.logged.push_back(d);
  }
  auto body = json_of(send(verb::get, "/api/v1/decisions?since=1&limit=1"));
  EXPECT_EQ(body["decisions"].size(), 1u);
  EXPECT_EQ(body["next"], 2);
  body = json_of(send(verb::get, "/api/v1/decisions?element=e3"));
  EXPECT_EQ(world_.last_element_filter, "e3");
  EXPECT_EQ(body["next"], 3);
  EXPECT_EQ(json_of(send(verb::get, "/api/v1/decisions?since=9"))["next"], 9);
  for (const std::string target : {"/api/v1/decisions?since=abc", "/api/v1/decisions?limit=0",
                                   "/api/v1/decisions?limit=10001", "/api/v1/decisions?since=-1"}) {
    const auto response = send(verb::get, target);
    EXPECT_EQ(status_of(response), 400) << target;
    EXPECT_EQ(error_of(response), "bad_request");
  }
}

TEST_F(ReadHandlersTest, RulesStatusHasRelativePaths) {
  const auto body = json_of(send(verb::get, "/api/v1/rules"));
  EXPECT_EQ(body["generation"], 1);
  EXPECT_EQ(body["files"][0]["path"], "prolog/world_model.pl");
}

TEST_F(ReadHandlersTest, AnEmptyGridIs404) {
  for (const std::string target : {"/api/v1/grid", "/api/v1/grid/map.yaml", "/api/v1/grid/map.pgm"}) {
    const auto response = send(verb::get, target);
    EXPECT_EQ(status_of(response), 404) << target;
    EXPECT_EQ(error_of(response), "empty_grid");
  }
}

TEST_F(ReadHandlersTest, GridLayersComeAsJsonOrPgmWithTheMapServerYaml) {
  fill_grid();
  auto response = send(verb::get, "/api/v1/grid?layer=ds_conflict");
  ASSERT_EQ(status_of(response), 200);
  auto body = json_of(response);
  ASSERT_TRUE(body.is_object()) << response.body().substr(0, 200);
  EXPECT_EQ(body["layer"], "ds_conflict");
  EXPECT_EQ(body["revision"], 4);
  EXPECT_EQ(body["data"].size(), body["width"].get<std::size_t>() * body["height"].get<std::size_t>());
  response = send(verb::get, "/api/v1/grid?bbox=0,0,1,1");
  body = json_of(response);
  EXPECT_EQ(body["width"], 20);
  EXPECT_EQ(body["height"], 20);
  response = send(verb::get, "/api/v1/grid?format=pgm&bbox=0,0,1,1");
  ASSERT_EQ(status_of(response), 200);
  EXPECT_EQ(response[http::field::content_type], "image/x-portable-graymap");
  EXPECT_EQ(response.body().rfind("P5\n", 0), 0u);
  EXPECT_EQ(send(verb::get, "/api/v1/grid/map.pgm?bbox=0,0,1,1").body(), response.body());
  response = send(verb::get, "/api/v1/grid/map.yaml?bbox=0,0,1,1");
  ASSERT_EQ(status_of(response), 200);
  EXPECT_NE(response.body().find("image: map.pgm\n"), std::string::npos);
  EXPECT_NE(response.body().find("origin: [0, 0, 0.0]\n"), std::string::npos);
  for (const std::string target :
       {"/api/v1/grid?layer=heat", "/api/v1/grid?format=png", "/api/v1/grid?bbox=1,1,0,0", "/api/v1/grid?bbox=0,0,1",
        "/api/v1/grid?bbox=0,0,1e9,1e9", "/api/v1/grid/map.yaml?bbox=a,b,c,d"}) {
    response = send(verb::get, target);
    EXPECT_EQ(status_of(response), 400) << target;
  }
}

TEST_F(ReadHandlersTest, MapQualityScoresTheElementsAgainstTheBayesGrid) {
  fill_grid();  // an arc of walls 2 m from the origin, bearings −0.5 … 0.5 rad
  world_.state().elements.clear();
  world::Element e;
  e.number = 1;
  e.segment = fusion::LineSegment::from_points({2.0, -0.1}, {2.0, 0.1}, Eigen::Matrix2d::Identity() * 1e-4);
  world_.state().elements.put(e);
  // Scan lines matched to it: one inside the 95 % gate, one outside; a CAD-edge match and a client's do not count.
  const auto logged = [](std::int64_t seq, const char* origin, double d2, bool cad) {
    auto d = FakeWorldPort::decision(rules::Action::merge, "e1");
    d.seq = seq;
    d.origin = origin;
    d.mahalanobis_sq = d2;
    d.matched_element = cad ? "wall/0" : "e1";
    if (cad) d.matched_object = "wall";
    return d;
  };
  world_.logged = {logged(1, "scan", 1.0, false), logged(2, "scan", 9.0, false), logged(3, "scan", 1.0, true),
                   logged(4, "client", 9.0, false)};
  world_.state().last_decision_seq = 4;
  auto body = json_of(send(verb::get, "/api/v1/map/quality"));
  ASSERT_TRUE(body.is_object());
  EXPECT_EQ(body["elements"], 1);
  EXPECT_NEAR(body["total_length_m"].get<double>(), 0.2, 1e-12);
  EXPECT_GE(body["precision"].get<double>(), 0.99);  // the element lies on the arc
  EXPECT_GT(body["recall"].get<double>(), 0.05);     // ... but explains only the arc's middle
  EXPECT_LT(body["recall"].get<double>(), 0.3);
  EXPECT_EQ(body["redundancy"].get<double>(), 0.0);
  EXPECT_EQ(body["calibration"].get<double>(), 0.5);
  EXPECT_EQ(body["calibration_samples"], 2);
  EXPECT_EQ(body["grid_revision"], 4);
  EXPECT_EQ(body["definitions"]["occupied_probability"], 0.65);
  // The same wall kept twice is all redundant.
  e.number = 2;
  world_.state().elements.put(e);
  body = json_of(send(verb::get, "/api/v1/map/quality"));
  EXPECT_NEAR(body["redundancy"].get<double>(), 1.0, 1e-9);
  // No scan line matched yet: calibration is null, not a number.
  world_.logged.clear();
  body = json_of(send(verb::get, "/api/v1/map/quality"));
  EXPECT_TRUE(body["calibration"].is_null());
}

TEST_F(ReadHandlersTest, APlainGetOfTheEventsWebSocketIsToldToUpgrade) {
  const auto response = send(verb::get, "/api/v1/events");
  EXPECT_EQ(status_of(response), 426);
  EXPECT_EQ(error_of(response), "upgrade_required");
  EXPECT_EQ(response[http::field::upgrade], "websocket");
}

TEST_F(ReadHandlersTest, AHostThatIsNotAllowedIs421ForEveryRoute) {
  options_.allowed_hosts = {"localhost"};
  auto request = make_request(verb::get, "/api/v1/health");
  request.set(http::field::host, "attacker.example:8080");
  EXPECT_EQ(status_of(send(request)), 421);
  request.set(http::field::host, "localhost:8080");
  EXPECT_EQ(status_of(send(request)), 200);
}

TEST_F(ReadHandlersTest, ServiceFailuresBecomeTheirStatus) {
  world_.fail_next(std::make_exception_ptr(storage::StorageError("disk I/O error")));
  auto response = send(verb::get, "/api/v1/decisions");
  EXPECT_EQ(status_of(response), 503);
  EXPECT_EQ(error_of(response), "storage_error");
}

}  // namespace
}  // namespace wm::testing
