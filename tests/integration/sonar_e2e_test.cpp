// Sonar judged by the laser, through the running wmd: a phantom sonar return in space the laser has seen free stays
// out of the fused grid but shows in the sonar-only layer and in the laser-vs-sonar conflict; the DS decision layer
// answers occupied and free; the gate's counts are served; laser-only and sonar-only layers come back the same after
// a crash (journal replay) and after a clean restart (rebuilt from the journal beside the stored fused tiles).
#include <atomic>
#include <string>
#include <thread>
#include <vector>

#include "e2e_fixture.h"
#include "grid_room.h"

namespace wm::testing {
namespace {

using namespace grid_room;

// One transducer at (4, 3) looking east: the room's east wall is 4 m away, the reading says 2 m (cross talk).
json phantom_sonar() {
  return {{"sensor", "sonar"}, {"source", "robot-2"}, {"pose", {{"x", 4}, {"y", 3}, {"theta", 0}}},
          {"angles", {0.0}},   {"ranges", {2.0}},     {"beam_width", 0.5236},
          {"range_max", 6.0},  {"sigma_range", 0.02}};
}

class SonarGateTest : public GridTest {
 protected:
  double cell(const std::string& layer, double x, double y) {
    const auto body =
        get_json("/api/v1/grid?layer=" + layer + "&bbox=" + std::to_string(x - 0.01) + "," + std::to_string(y - 0.01) +
                 "," + std::to_string(x + 0.01) + "," + std::to_string(y + 0.01));
    EXPECT_EQ(body["layer"], layer);
    return body["data"][0].is_null() ? -1.0 : body["data"][0].get<double>();
  }
  void map_the_room() {
    for (int k = 0; k < 3; ++k) {
      post_scan(room_scan(3, 3, 0.0));
      post_scan(room_scan(5, 2, 0.5));
    }
  }
};

TEST_F(SonarGateTest, APhantomStaysOutOfTheFusedGridAndShowsWhereSensorsDisagree) {
  map_the_room();
  EXPECT_FALSE(get_json("/api/v1/grid/tiles")["sonar"]["seen"].get<bool>());
  EXPECT_EQ(cell("sonar_bayes", 5.5, 3.0), -1.0) << "no sonar yet";
  for (int k = 0; k < 5; ++k) post_scan(phantom_sonar());

  EXPECT_LT(cell("bayes", 6.0, 3.0), 0.5) << "the phantom's arc stays free in the fused grid";
  EXPECT_GT(cell("sonar_bayes", 6.0, 3.0), 0.65) << "the sonar-only grid holds the reading as it came";
  EXPECT_GT(cell("laser_sonar_conflict", 6.0, 3.0), 0.3) << "laser free, sonar occupied";
  EXPECT_LT(cell("laser_sonar_conflict", 5.0, 3.0), 0.1) << "both free inside the cone";
  EXPECT_EQ(cell("ds_decision", 5.0, 3.0), 0.0) << "free";
  EXPECT_EQ(cell("ds_decision", 8.01, 3.0), 1.0) << "the east wall: occupied";
  EXPECT_EQ(cell("laser_ds_decision", 8.01, 3.0), 1.0);
  EXPECT_EQ(cell("laser_bayes", 6.0, 3.0), cell("bayes", 6.0, 3.0)) << "the phantom changed nothing of the fused grid";

  const auto sonar = get_json("/api/v1/grid/tiles")["sonar"];
  EXPECT_TRUE(sonar["seen"].get<bool>());
  EXPECT_TRUE(sonar["gated_by_laser"].get<bool>());
  EXPECT_EQ(sonar["scans"], 5);
  EXPECT_EQ(sonar["readings"]["phantom"], 5) << sonar.dump();

  // Every layer is listed, and an unknown one is refused naming them.
  const auto layers = get_json("/api/v1/grid/tiles")["layers"];
  EXPECT_EQ(layers.size(), 9u);
  const auto refused = send_json("GET", "/api/v1/grid?layer=sonar", json(), 400);
  EXPECT_NE(refused.dump().find("laser_sonar_conflict"), std::string::npos) << refused.dump();
  // A derived layer comes as tiles and as PGM too.
  const auto tiles = get_json("/api/v1/grid/tiles");
  ASSERT_FALSE(tiles["tiles"].empty());
  const auto& first = tiles["tiles"][0];
  const auto tile = call("GET", "/api/v1/grid/tiles/ds_decision/" + std::to_string(first[0].get<int>()) + "/" +
                                    std::to_string(first[1].get<int>()));
  EXPECT_EQ(tile.status, 200);
  EXPECT_EQ(tile.body.size(), 4u * 64 * 64);
  EXPECT_EQ(call("GET", "/api/v1/grid?layer=laser_sonar_conflict&format=pgm").status, 200);
}

TEST_F(SonarGateTest, SideGridsComeBackAfterACrashAndAfterARestart) {
  map_the_room();
  for (int k = 0; k < 3; ++k) post_scan(phantom_sonar());
  post_scan(room_scan(4, 4, 1.0));  // a laser scan after the sonar: it goes into the laser-only grid too
  const std::string box = "&bbox=3,1,8.5,5";
  const auto laser = get_raw("/api/v1/grid?layer=laser_bayes" + box);
  const auto sonar = get_raw("/api/v1/grid?layer=sonar_bayes" + box);
  const auto fused = get_raw("/api/v1/grid?layer=bayes" + box);
  const auto counts = get_json("/api/v1/grid/tiles")["sonar"];
  server_->crash();  // nothing flushed: every scan comes back through the journal
  start();
  EXPECT_EQ(json::parse(get_raw("/api/v1/grid?layer=laser_bayes" + box))["data"], json::parse(laser)["data"]);
  EXPECT_EQ(json::parse(get_raw("/api/v1/grid?layer=sonar_bayes" + box))["data"], json::parse(sonar)["data"]);
  EXPECT_EQ(get_json("/api/v1/grid/tiles")["sonar"], counts);
  restart();  // a clean stop flushes the fused tiles; the side grids are rebuilt from the journal
  EXPECT_EQ(json::parse(get_raw("/api/v1/grid?layer=bayes" + box))["data"], json::parse(fused)["data"]);
  EXPECT_EQ(json::parse(get_raw("/api/v1/grid?layer=laser_bayes" + box))["data"], json::parse(laser)["data"]);
  EXPECT_EQ(json::parse(get_raw("/api/v1/grid?layer=sonar_bayes" + box))["data"], json::parse(sonar)["data"]);
  EXPECT_EQ(get_json("/api/v1/grid/tiles")["sonar"], counts);
}

// The grid component's sonar_gate parameter, changed while the network runs: a bad value changes nothing, off lets
// the phantom in, on keeps it out again.
TEST_F(SonarGateTest, TheGateIsAParameterOfTheGridComponentChangedWhileItRuns) {
  map_the_room();
  const std::string route = "/api/v1/network/components/grid/params";
  send_json("PUT", route, {{"sonar_gate", "maybe"}}, 422);
  send_json("PUT", route, {{"sonar_gate", 1}}, 422);
  const auto network = get_json("/api/v1/network");
  bool listed = false;
  for (const auto& c : network["components"])
    if (c["name"] == "grid") listed = c["params"]["sonar_gate"] == "on";
  EXPECT_TRUE(listed) << network["components"].dump();
  for (int k = 0; k < 3; ++k) post_scan(phantom_sonar());
  EXPECT_EQ(get_json("/api/v1/grid/tiles")["sonar"]["readings"]["phantom"], 3);
  send_json("PUT", route, {{"sonar_gate", false}});
  EXPECT_FALSE(get_json("/api/v1/grid/tiles")["sonar"]["gated_by_laser"].get<bool>());
  for (int k = 0; k < 10; ++k) post_scan(phantom_sonar());
  EXPECT_GT(cell("bayes", 6.0, 3.0), 0.5) << "ungated, the phantom went into the fused grid";
  EXPECT_EQ(get_json("/api/v1/grid/tiles")["sonar"]["readings"]["phantom"], 3);
  send_json("PUT", route, {{"sonar_gate", "on"}});
  post_scan(phantom_sonar());
  EXPECT_EQ(get_json("/api/v1/grid/tiles")["sonar"]["readings"]["phantom"], 4) << "judged by the laser-only grid again";
}

// Laser and sonar posted at once by several robots reach the grid on two queues; the grid takes them in journal
// order, so the live fused grid and the gate's counts are what a replay of the journal (after a crash) rebuilds.
TEST_F(SonarGateTest, ConcurrentLaserAndSonarGiveTheGridAReplayRebuilds) {
  map_the_room();
  std::atomic<int> failures{0};
  std::vector<std::thread> robots;
  for (int r = 0; r < 4; ++r)
    robots.emplace_back([&, r] {
      client::HttpClient http(server_->url());
      for (int i = 0; i < 15; ++i) {
        json body = phantom_sonar();
        if (r % 2 == 0) {
          body = room_scan(2.0 + 0.2 * i, 1.5 + r, 0.1 * i);
        } else {
          body["source"] = "sonar-" + std::to_string(r);
          body["ranges"] = {1.0 + 0.2 * i};
        }
        const auto answer = http.request("POST", "/api/v1/scans", body.dump());
        if (answer.status != 200) ++failures;
      }
    });
  for (auto& t : robots) t.join();
  ASSERT_EQ(failures, 0);
  const std::string box = "&bbox=0,0,8.5,6.5";
  const auto fused = get_raw("/api/v1/grid?layer=bayes" + box);
  const auto counts = get_json("/api/v1/grid/tiles")["sonar"];
  EXPECT_EQ(counts["scans"], 30);
  server_->crash();  // nothing flushed: the whole grid is rebuilt from the journal, in its order
  start();
  EXPECT_EQ(json::parse(get_raw("/api/v1/grid?layer=bayes" + box))["data"], json::parse(fused)["data"]);
  EXPECT_EQ(get_json("/api/v1/grid/tiles")["sonar"], counts);
}

class UngatedSonarTest : public GridTest {
 protected:
  void SetUp() override {
    extra_args_ = {"--sonar-gate", "off"};
    ServerFixture::SetUp();
  }
};

TEST_F(UngatedSonarTest, WithoutTheGateThePhantomIsInTheFusedGrid) {
  for (int k = 0; k < 3; ++k) post_scan(room_scan(3, 3, 0.0));
  for (int k = 0; k < 10; ++k) post_scan(phantom_sonar());
  const auto arc = get_json("/api/v1/grid?bbox=5.99,2.99,6.01,3.01");
  EXPECT_GT(arc["data"][0].get<double>(), 0.65) << "ten sonar readings outweigh three laser views of free space";
  const auto sonar = get_json("/api/v1/grid/tiles")["sonar"];
  EXPECT_FALSE(sonar["gated_by_laser"].get<bool>());
  EXPECT_EQ(sonar["readings"]["phantom"], 0);
}

}  // namespace
}  // namespace wm::testing
