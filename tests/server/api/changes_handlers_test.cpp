// GET /api/v1/changes, POST /api/v1/changes/{id}/accept|reject, POST /api/v1/changes/undo and the as-built report's
// verdicts, through the router, against a fake of the service port.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "server/api/handlers.h"
#include "tests/server/api/api_test_helpers.h"

namespace wm::testing {
namespace {

using http::verb;

class ChangesHandlersTest : public ApiTest {
 protected:
  void SetUp() override {
    load_demo_plan();  // wall-n along y = 10 from x = 0 to 20, table-1 at (5, 5)
    // The grid saw through the wall from x = 4 to 6 (a door cut in), and an element stands where the plan has none.
    auto& report = *world_.plan_report_answer;
    world::EdgeEvidence wall;
    wall.object = 0;
    wall.edge = 0;
    wall.length_m = 20;
    wall.backed = 0.85;
    wall.seen_through = 0.1;
    wall.observed = 0.95;
    wall.seen_through_stretches = {{4, 6, 212}};
    wall.beams_through = 240;
    wall.beams_ended = 3100;
    report.edges = {wall};
    report.verdicts = {{"wall-n", 0, "partly_missing", {4, 6, 212}, "wall_partly_missing", "a door"}};
    report.grid_revision = 77;
    world::Element e;
    e.number = 12;
    e.segment = fusion::LineSegment::from_points({1, 2}, {4, 2}, Eigen::Matrix2d::Identity() * 1e-4);
    e.support = 6;
    e.origin = "scan";
    world_.state().elements.put(e);
    world::Element clutter = e;  // too short to be a wall
    clutter.number = 13;
    clutter.segment = fusion::LineSegment::from_points({1, 3}, {1.3, 3}, Eigen::Matrix2d::Identity() * 1e-4);
    world_.state().elements.put(clutter);
  }

  std::string id_of(const std::string& key) {
    const auto body = json_of(send(verb::get, "/api/v1/changes"));
    for (const auto& c : body["changes"])
      if (c["key"] == key) return c["id"];
    return "";
  }
};

TEST_F(ChangesHandlersTest, ListsMissingStretchesAndNewWallsWithTheirEvidence) {
  const auto response = send(verb::get, "/api/v1/changes");
  ASSERT_EQ(status_of(response), 200);
  const auto body = json_of(response);
  EXPECT_EQ(body["grid_revision"], 77);
  const auto& list = body["changes"];
  ASSERT_EQ(list.size(), 2u) << body.dump(2);
  const auto& door = list[0];
  EXPECT_EQ(door["kind"], "wall_partly_missing");
  EXPECT_EQ(door["key"], "partly_missing:wall-n/0@4.00-6.00");
  EXPECT_EQ(door["object"], "wall-n");
  EXPECT_EQ(door["edge"], "wall-n/0");
  EXPECT_NEAR(door["length"].get<double>(), 2.0, 1e-9);
  // 4 m to 6 m from the edge's first end, wherever the edge starts.
  const auto edge = world_.state().objects[0].body.world_edge(0, Eigen::Matrix2d::Zero());
  const Eigen::Vector2d from = edge.p0() + 0.2 * (edge.p1() - edge.p0()),
                        to = edge.p0() + 0.3 * (edge.p1() - edge.p0());
  EXPECT_NEAR(door["p0"][0].get<double>(), from.x(), 1e-9);
  EXPECT_NEAR(door["p1"][0].get<double>(), to.x(), 1e-9);
  EXPECT_NEAR(door["p0"][1].get<double>(), 10.0, 1e-9);
  EXPECT_EQ(door["evidence"]["beams_through"], 240);
  EXPECT_NEAR(door["confidence"].get<double>(), 0.1 / 0.95, 1e-9);
  const std::string id = door["id"];
  EXPECT_EQ(id.size(), 13u);
  EXPECT_EQ(id[0], 'c');
  const auto& wall = list[1];
  EXPECT_EQ(wall["kind"], "new_wall");
  EXPECT_EQ(wall["element"], "e12");
  EXPECT_EQ(wall["support"], 6);
  // The same key gives the same id on every listing.
  EXPECT_EQ(id_of("partly_missing:wall-n/0@4.00-6.00"), id);
}

TEST_F(ChangesHandlersTest, AcceptAndRejectNameAListedChangeAndTheDecider) {
  const auto id = id_of("new:e12");
  ASSERT_FALSE(id.empty());
  auto response = send(verb::post, "/api/v1/changes/" + id + "/accept");
  ASSERT_EQ(status_of(response), 200) << response.body();
  EXPECT_EQ(json_of(response)["decision"]["action"], "accept");
  EXPECT_EQ(world_.last_change, (std::pair<std::string, bool>{id, true}));
  EXPECT_EQ(world_.last_decider, "client");
  response = send(verb::post, "/api/v1/changes/" + id + "/reject", R"({"source": "alice"})");
  ASSERT_EQ(status_of(response), 200) << response.body();
  EXPECT_EQ(json_of(response)["decision"]["action"], "reject");
  EXPECT_EQ(world_.last_change, (std::pair<std::string, bool>{id, false}));
  EXPECT_EQ(world_.last_decider, "alice");
  response = send(verb::post, "/api/v1/changes/undo");
  ASSERT_EQ(status_of(response), 200) << response.body();
  EXPECT_EQ(json_of(response)["decision"]["action"], "undo");
}

TEST_F(ChangesHandlersTest, BadIdsAndBodiesAreRefusedAndChangeNothing) {
  const auto id = id_of("new:e12");
  for (const std::string& bad :
       std::vector<std::string>{"c0000", "C" + id.substr(1), id + "0", "x" + id.substr(1), "c00000000000g"}) {
    const auto response = send(verb::post, "/api/v1/changes/" + bad + "/accept");
    EXPECT_EQ(status_of(response), 404) << bad;
    EXPECT_EQ(error_of(response), "not_found");
  }
  // Well formed but not listed: the service says so.
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/changes/c0123456789ab/accept")), 404);
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/changes/" + id + "/accept", R"({"who": "x"})")), 400);
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/changes/" + id + "/accept", R"({"source": 3})")), 400);
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/changes/" + id + "/accept", "[1]")), 400);
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/changes/" + id + "/accept", "yes", "text/plain")), 415);
  EXPECT_EQ(status_of(send(verb::get, "/api/v1/changes/" + id + "/accept")), 405);
  EXPECT_FALSE(world_.last_change.has_value());
}

TEST_F(ChangesHandlersTest, DecisionsNeedTheTokenWhenOneIsConfigured) {
  const auto id = id_of("new:e12");
  options_.token = "s3cret";
  for (const std::string& target : std::vector<std::string>{
           "/api/v1/changes/" + id + "/accept", "/api/v1/changes/" + id + "/reject", "/api/v1/changes/undo"}) {
    auto request = make_request(verb::post, target, "");
    EXPECT_EQ(status_of(send(request)), 401) << target;
    request.set(http::field::authorization, "Bearer s3cret");
    EXPECT_EQ(status_of(send(request)), 200) << target;
  }
  EXPECT_EQ(status_of(send(verb::get, "/api/v1/changes")), 200);  // reading needs none
}

TEST_F(ChangesHandlersTest, AsBuiltReportCarriesVerdictsAndEvidence) {
  const auto body = json_of(send(verb::get, "/api/v1/report/as-built"));
  EXPECT_EQ(body["summary"]["partly_missing"], 1);
  const auto& wall = body["objects"][0];
  EXPECT_EQ(wall["status"], "partly_missing");
  ASSERT_EQ(wall["verdicts"].size(), 1u);
  EXPECT_EQ(wall["verdicts"][0]["edge"], "wall-n/0");
  const auto edge = world_.state().objects[0].body.world_edge(0, Eigen::Matrix2d::Zero());
  EXPECT_NEAR(wall["verdicts"][0]["p0"][0].get<double>(), (edge.p0() + 0.2 * (edge.p1() - edge.p0())).x(), 1e-9);
  EXPECT_EQ(wall["edges"][0]["beams_ended"], 3100);
  EXPECT_EQ(wall["edges"][0]["seen_through_stretches"][0]["beams_through"], 212);
  // The object's history (wmctl explain) says the same.
  const auto history = json_of(send(verb::get, "/api/v1/objects/wall-n/history"));
  EXPECT_EQ(history["as_built"]["status"], "partly_missing");
  EXPECT_EQ(history["as_built"]["edges"][0]["beams_through"], 240);
}

}  // namespace
}  // namespace wm::testing
