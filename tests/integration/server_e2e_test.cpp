#include <Eigen/Core>
#include <cmath>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

constexpr double kTheta = 0.3;

Eigen::Vector2d table_to_world(const json& pose, double x, double y) {
  const double c = std::cos(pose["theta"].get<double>()), s = std::sin(pose["theta"].get<double>());
  return {pose["x"].get<double>() + c * x - s * y, pose["y"].get<double>() + s * x + c * y};
}

Eigen::Vector2d vec(const json& p) { return {p[0].get<double>(), p[1].get<double>()}; }

json find_object(const json& map, const std::string& id) {
  for (const auto& o : map["objects"])
    if (o["id"] == id) return o;
  ADD_FAILURE() << "no object " << id;
  return {};
}

json segment(Eigen::Vector2d a, Eigen::Vector2d b) { return {{"p0", {a.x(), a.y()}}, {"p1", {b.x(), b.y()}}}; }

// The foundation issue's scenario: one decision of each kind, then a restart on the same file.
TEST_F(ServerFixture, FourDecisionsApplyAndSurviveARestart) {
  const auto loaded = send_json("PUT", "/api/v1/floorplan", lab_plan());
  EXPECT_EQ(loaded["objects"], 2);
  EXPECT_EQ(loaded["edges"], 5);
  const json map0 = get_json("/api/v1/map");
  const json wall0 = find_object(map0, "wall-n");
  const json table0 = find_object(map0, "table-1");

  // add: a cardboard wall in free space; merge: the same wall seen again, further along.
  json first = send_json("POST", "/api/v1/primitives",
                         {{"source", "robot-1"}, {"stamp", 1.0}, {"segments", {segment({10, 3}, {13, 3.02})}}});
  ASSERT_EQ(first["decisions"].size(), 1u);
  EXPECT_EQ(first["decisions"][0]["action"], "add");
  EXPECT_EQ(first["decisions"][0]["rule"], "unmatched_added");
  const std::string element = first["decisions"][0]["element"];
  const json e_before = get_json("/api/v1/elements/" + element);

  // The table's bottom edge (local y = −0.4), seen 3 cm further out along its outward normal, on its middle part.
  const Eigen::Vector2d normal(std::sin(kTheta), -std::cos(kTheta));
  const auto table_pose = table0["pose"];
  const Eigen::Vector2d ta = table_to_world(table_pose, -0.4, -0.4) + 0.03 * normal;
  const Eigen::Vector2d tb = table_to_world(table_pose, 0.4, -0.4) + 0.03 * normal;

  json second = send_json("POST", "/api/v1/primitives",
                          {{"source", "robot-1"},
                           {"stamp", 2.0},
                           {"segments",
                            {segment({12, 3.015}, {16, 3.01}),  // merge into the element
                             segment({4, 10.005}, {9, 9.998}),  // delete: confirms the solid wall
                             segment(ta, tb)}}});               // rigid_adjust of the table
  ASSERT_EQ(second["decisions"].size(), 3u);
  EXPECT_EQ(second["decisions"][0]["action"], "merge");
  EXPECT_EQ(second["decisions"][0]["element"], element);
  EXPECT_EQ(second["decisions"][1]["action"], "delete");
  EXPECT_EQ(second["decisions"][1]["object"], "wall-n");
  EXPECT_EQ(second["decisions"][1]["rule"], "solid_confirmed");
  EXPECT_EQ(second["decisions"][2]["action"], "rigid_adjust");
  EXPECT_EQ(second["decisions"][2]["object"], "table-1");
  EXPECT_EQ(second["decisions"][2]["rule"], "not_deformable_rigid");
  for (const auto& d : second["decisions"]) EXPECT_FALSE(d["explanation"].get<std::string>().empty());

  const json map1 = get_json("/api/v1/map");
  // The wall is unchanged (only its confirmation count moved).
  json wall1 = find_object(map1, "wall-n");
  EXPECT_EQ(wall1["confirmations"], 1);
  wall1.erase("confirmations");
  wall1.erase("updated_version");
  json wall0_cmp = wall0;
  wall0_cmp.erase("confirmations");
  wall0_cmp.erase("updated_version");
  EXPECT_EQ(wall1, wall0_cmp);

  // The free element is fused: smaller covariance, extent joined over both observations (10..16 m in x).
  const json e_after = get_json("/api/v1/elements/" + element);
  EXPECT_EQ(e_after["support"], 2);
  EXPECT_LT(e_after["cov"][0][0].get<double>(), e_before["cov"][0][0].get<double>());
  EXPECT_LT(e_after["cov"][1][1].get<double>(), e_before["cov"][1][1].get<double>());
  const double x_min = std::min(e_after["p0"][0].get<double>(), e_after["p1"][0].get<double>());
  const double x_max = std::max(e_after["p0"][0].get<double>(), e_after["p1"][0].get<double>());
  EXPECT_NEAR(x_min, 10.0, 0.01);
  EXPECT_NEAR(x_max, 16.0, 0.01);

  // The table moved as a rigid body toward the observation.
  const json table1 = find_object(map1, "table-1");
  const Eigen::Vector2d moved(table1["pose"]["x"].get<double>() - table_pose["x"].get<double>(),
                              table1["pose"]["y"].get<double>() - table_pose["y"].get<double>());
  EXPECT_GT(moved.dot(normal), 0.005) << "pose should move toward the observed edge";
  EXPECT_LT(moved.dot(normal), 0.0301);
  const auto& edges0 = table0["edges"];
  const auto& edges1 = table1["edges"];
  ASSERT_EQ(edges1.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    const Eigen::Vector2d d0 = vec(edges0[k]["p1"]) - vec(edges0[k]["p0"]);
    const Eigen::Vector2d d1 = vec(edges1[k]["p1"]) - vec(edges1[k]["p0"]);
    EXPECT_NEAR(d1.norm(), d0.norm(), 1e-9) << "edge " << k << " length";
    const std::size_t next = (k + 1) % 4;
    const Eigen::Vector2d n0 = vec(edges0[next]["p1"]) - vec(edges0[next]["p0"]);
    const Eigen::Vector2d n1 = vec(edges1[next]["p1"]) - vec(edges1[next]["p0"]);
    const double angle0 = std::atan2(d0.x() * n0.y() - d0.y() * n0.x(), d0.dot(n0));
    const double angle1 = std::atan2(d1.x() * n1.y() - d1.y() * n1.x(), d1.dot(n1));
    EXPECT_NEAR(angle1, angle0, 1e-9) << "angle between edges " << k << " and " << next;
  }
  EXPECT_LT(table1["pose_cov"][0][0].get<double>() + table1["pose_cov"][1][1].get<double>(),
            table0["pose_cov"][0][0].get<double>() + table0["pose_cov"][1][1].get<double>());

  // The decision log has all four, in order.
  const json log = get_json("/api/v1/decisions");
  ASSERT_EQ(log["decisions"].size(), 4u);
  EXPECT_EQ(log["decisions"][0]["action"], "add");
  EXPECT_EQ(log["decisions"][3]["action"], "rigid_adjust");
  EXPECT_EQ(get_json("/api/v1/decisions?since=2")["decisions"].size(), 2u);

  // A restart on the same file gives the identical map and decision log.
  // The same map, byte for byte, but for the token of the server run.
  const auto map_without_run = [&] {
    auto map = json::parse(call("GET", "/api/v1/map").body);
    EXPECT_EQ(map.erase("server_instance"), 1u);
    return map.dump();
  };
  const std::string map_text = map_without_run();
  const std::string log_text = call("GET", "/api/v1/decisions").body;
  const std::string plan_text = call("GET", "/api/v1/floorplan").body;
  restart();
  EXPECT_EQ(map_without_run(), map_text);
  EXPECT_EQ(call("GET", "/api/v1/decisions").body, log_text);
  EXPECT_EQ(call("GET", "/api/v1/floorplan").body, plan_text);

  // And it goes on where it stopped: the next element number and decision sequence continue.
  json third = send_json("POST", "/api/v1/primitives", {{"segments", {segment({1, 1}, {1, 3})}}});
  EXPECT_EQ(third["decisions"][0]["seq"], 5);
  EXPECT_EQ(third["decisions"][0]["element"], "e2");
}

TEST_F(ServerFixture, HealthReportsTheLoadedRules) {
  const json health = get_json("/api/v1/health");
  EXPECT_EQ(health["status"], "ok");
  ASSERT_FALSE(health["rules"]["files"].empty());
  EXPECT_NE(health["rules"]["files"][0]["path"].get<std::string>().find("world_model.pl"), std::string::npos);
}

TEST_F(ServerFixture, ObjectsAndElementsHaveTheirOwnResources) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  const json table = get_json("/api/v1/objects/table-1");
  EXPECT_EQ(table["kind"], "table");
  EXPECT_EQ(table["edges"].size(), 4u);
  EXPECT_EQ(table["edges"][0]["id"], "table-1/0");
  EXPECT_EQ(get_json("/api/v1/objects")["objects"].size(), 2u);
  EXPECT_EQ(call("GET", "/api/v1/objects/nope").status, 404);
  EXPECT_EQ(call("GET", "/api/v1/elements/e99").status, 404);
}

}  // namespace
}  // namespace wm::testing
