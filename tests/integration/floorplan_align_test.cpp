// Placing a floor plan through the running wmd: the real GDC1 plan drawn in its own frame (displaced by a known
// similarity), a robot's 360° laser ray-cast inside the real building (a table a little off its drawn place),
// POST /api/v1/floorplan/align, then the rules at work on the placed plan; by hand, undo, restart, georeference.
#include <Eigen/Geometry>
#include <cmath>
#include <iostream>
#include <numbers>

#include "e2e_fixture.h"
#include "support/test_data.h"
#include "tools/raycast/raycast.h"

namespace wm::testing {
namespace {

using raycast::PlanLine;

constexpr double kDeg = std::numbers::pi / 180.0;

// A placement x ↦ s·R(θ)·x + t of the drawing in the world.
struct Placement {
  double x, y, theta, scale;
  Eigen::Vector2d to_world(const Eigen::Vector2d& p) const {
    return scale * (Eigen::Rotation2Dd(theta) * p) + Eigen::Vector2d(x, y);
  }
  Eigen::Vector2d to_drawing(const Eigen::Vector2d& w) const {
    return Eigen::Rotation2Dd(-theta) * (w - Eigen::Vector2d(x, y)) / scale;
  }
};

// The table as built: 1.2 m × 0.8 m beside the corridor south of the route from node 2 to node 4.
const Eigen::Vector2d kTableBuilt(-22.35, 5.9);
constexpr double kTableBuiltTheta = 0.09;
// ... and as drawn (in the world): 15 cm and 5° off.
const Eigen::Vector2d kTableDrawn(-22.5, 6.0);
constexpr double kTableDrawnTheta = 0.0;
const std::vector<Eigen::Vector2d> kTableOutline{{-0.6, -0.4}, {0.6, -0.4}, {0.6, 0.4}, {-0.6, 0.4}};

std::vector<PlanLine> table_lines(const Eigen::Vector2d& at, double theta) {
  std::vector<PlanLine> lines;
  for (std::size_t i = 0; i < kTableOutline.size(); ++i)
    lines.push_back({at + Eigen::Rotation2Dd(theta) * kTableOutline[i],
                     at + Eigen::Rotation2Dd(theta) * kTableOutline[(i + 1) % kTableOutline.size()]});
  return lines;
}

std::vector<PlanLine> gdc1_walls() {
  return raycast::read_vectormap(
      real_data("amrl-vectormaps/GDC1.vectormap.json", "plans/GDC1.vectormap.json").string());
}

// The JSON plan of GDC1 drawn in the frame that `truth` places in the world: every wall solid, and the table.
json drawn_plan(const std::vector<PlanLine>& walls, const Placement& truth) {
  json objects = json::array();
  for (std::size_t i = 0; i < walls.size(); ++i) {
    const auto a = truth.to_drawing(walls[i].p0), b = truth.to_drawing(walls[i].p1);
    objects.push_back({{"id", "wall-" + std::to_string(i)},
                       {"kind", "wall"},
                       {"attributes", {"solid"}},
                       {"pose", {{"x", 0}, {"y", 0}, {"theta", 0}}},
                       {"segments", {{{a.x(), a.y()}, {b.x(), b.y()}}}}});
  }
  const auto table = truth.to_drawing(kTableDrawn);
  json outline = json::array();
  for (const auto& p : kTableOutline) outline.push_back({p.x() / truth.scale, p.y() / truth.scale});
  objects.push_back({{"id", "table-1"},
                     {"kind", "table"},
                     {"attributes", {"not_deformable"}},
                     {"pose", {{"x", table.x()}, {"y", table.y()}, {"theta", kTableDrawnTheta - truth.theta}}},
                     {"polygon", outline}});
  return {{"name", "GDC1 (drawn displaced)"}, {"units", "m"}, {"objects", objects}};
}

json scan_json(const fusion::LaserScan& scan) {
  return {{"sensor", "laser"},
          {"source", "robot-1"},
          {"pose", {{"x", scan.sensor_pose.x_m}, {"y", scan.sensor_pose.y_m}, {"theta", scan.sensor_pose.theta_rad}}},
          {"angle_min", scan.angle_min_rad},
          {"angle_increment", scan.angle_increment_rad},
          {"ranges", scan.ranges_m},
          {"range_min", scan.range_min_m},
          {"range_max", scan.range_max_m},
          {"sigma_range", 0.01}};
}

// The placement's distance from `truth`: the farthest a drawn point of the building lands from where it belongs.
double worst_point_error(const json& placement, const Placement& truth, const std::vector<PlanLine>& walls) {
  const Placement found{placement["x"], placement["y"], placement["theta"], placement["scale"]};
  double worst = 0;
  for (const auto& w : walls)
    for (const auto& p : {w.p0, w.p1}) worst = std::max(worst, (found.to_world(truth.to_drawing(p)) - p).norm());
  return worst;
}

class FloorPlanAlignTest : public ServerFixture {
 protected:
  // Posts the scans; counts the actions of the decisions on their lines.
  std::map<std::string, int> post_scans(const std::vector<fusion::LaserScan>& scans) {
    std::map<std::string, int> actions;
    for (const auto& scan : scans) {
      const auto answer = send_json("POST", "/api/v1/scans", scan_json(scan));
      if (answer["lines"].is_null()) continue;
      for (const auto& d : answer["lines"]["decisions"]) ++actions[d["action"].get<std::string>()];
    }
    return actions;
  }
};

TEST_F(FloorPlanAlignTest, AGdc1PlanDrawnElsewhereIsAlignedAndTheRulesThenConfirmItsWalls) {
  const auto walls = gdc1_walls();
  auto world = walls;
  for (const auto& l : table_lines(kTableBuilt, kTableBuiltTheta)) world.push_back(l);
  const auto scans = raycast::simulate_scans(world, raycast::gdc1_route());
  // Drawn 8 m off and turned by 160°, about the building's centre.
  const Eigen::Vector2d centre(0.0, 0.0);
  const double theta = 160 * kDeg;
  const Eigen::Vector2d t = centre + Eigen::Rotation2Dd(theta) * (Eigen::Vector2d(6.0, -5.0) - centre);
  const Placement truth{t.x(), t.y(), theta, 1.0};

  send_json("PUT", "/api/v1/floorplan", drawn_plan(walls, truth));
  // Before: the plan lies elsewhere and the rules can only add what the robot sees.
  const auto before = post_scans(scans);
  const int lines_before = before.at("add") + (before.count("delete") ? before.at("delete") : 0) +
                           (before.count("merge") ? before.at("merge") : 0);
  EXPECT_LT(before.count("delete") ? before.at("delete") : 0, lines_before / 10);
  EXPECT_EQ(before.count("rigid_adjust"), 0u);

  // A preview changes nothing. (The search's wall-clock budget at its largest: a sanitizer build on a loaded machine
  // ran past the default 10 s.)
  const auto preview = send_json("POST", "/api/v1/floorplan/align", {{"apply", false}, {"time_budget_ms", 30000}});
  EXPECT_EQ(preview["verdict"], "preview") << preview.dump();
  EXPECT_FALSE(preview["applied"]);
  EXPECT_LT(worst_point_error(preview["best"], truth, walls), 0.05) << preview["best"].dump();
  EXPECT_EQ(get_json("/api/v1/floorplan")["placement"]["x"], 0.0);

  const auto aligned =
      send_json("POST", "/api/v1/floorplan/align",
                {{"apply", true}, {"redecide", true}, {"source", "operator"}, {"time_budget_ms", 30000}});
  ASSERT_EQ(aligned["verdict"], "applied") << aligned.dump();
  const auto& best = aligned["best"];
  EXPECT_LT(worst_point_error(best, truth, walls), 0.05) << best.dump();
  EXPECT_NEAR(std::remainder(best["theta"].get<double>() - truth.theta, 2 * std::numbers::pi), 0.0, 0.5 * kDeg);
  EXPECT_GT(best["score"].get<double>(), 0.8);
  EXPECT_FALSE(aligned["ambiguous"]);
  EXPECT_LT(aligned["seconds"].get<double>(), 10.0);
  EXPECT_EQ(aligned["decision"]["action"], "place");
  EXPECT_EQ(aligned["decision"]["rule"], "plan_aligned");
  EXPECT_EQ(aligned["decision"]["observer"], "operator");
  // The elements the displaced plan could not explain are now confirmed by it and go.
  const auto& redecided = aligned["redecided"];
  EXPECT_GT(redecided["actions"]["delete"].get<int>(), redecided["elements"].get<int>() / 2) << redecided["actions"];

  // The placement is part of the map, the plan's edges are in the world where the walls are.
  const auto plan = get_json("/api/v1/floorplan");
  EXPECT_NEAR(plan["placement"]["x"].get<double>(), truth.x, 0.05);
  const auto object = get_json("/api/v1/objects/wall-0");
  const Eigen::Vector2d edge_start(object["edges"][0]["p0"][0], object["edges"][0]["p0"][1]);
  EXPECT_LT(std::min((edge_start - walls[0].p0).norm(), (edge_start - walls[0].p1).norm()), 0.05);

  // The same drive again: the walls are confirmed, the table is moved to where it stands.
  const auto after = post_scans(scans);
  std::cout << "[figures] scan-line decisions before " << json(before).dump() << ", after " << json(after).dump()
            << "; redecided " << redecided["actions"].dump() << " of " << redecided["elements"]
            << " elements; aligned in " << aligned["seconds"] << " s, score " << best["score"] << ", coverage "
            << best["coverage"] << ", runner-up " << aligned["runner_up"].dump() << "\n";
  int lines_after = 0;
  for (const auto& [action, n] : after) lines_after += n;
  EXPECT_GT(after.count("delete") ? after.at("delete") : 0, lines_after / 2) << json(after).dump();
  EXPECT_GT(after.count("rigid_adjust") ? after.at("rigid_adjust") : 0, 0) << json(after).dump();
  const auto table = get_json("/api/v1/objects/table-1");
  EXPECT_LT((Eigen::Vector2d(table["pose"]["x"], table["pose"]["y"]) - kTableBuilt).norm(), 0.08) << table["pose"];

  // The placement survives a restart; undo goes back to the plan as drawn, logged.
  restart();
  EXPECT_NEAR(get_json("/api/v1/floorplan")["placement"]["theta"].get<double>(), best["theta"].get<double>(), 1e-12);
  const auto undone = send_json("POST", "/api/v1/floorplan/undo", json::object());
  EXPECT_EQ(undone["decision"]["rule"], "placement_undone");
  EXPECT_EQ(undone["placement"]["x"], 0.0);
  EXPECT_NEAR(undone["before"]["x"].get<double>(), best["x"].get<double>(), 1e-12);
  EXPECT_EQ(send_json("POST", "/api/v1/floorplan/undo", json::object(), 409)["error"], "conflict");
  const auto log = get_json("/api/v1/decisions?limit=10000&since=" +
                            std::to_string(aligned["decision"]["seq"].get<std::int64_t>() - 1))["decisions"];
  int placements = 0;
  for (const auto& d : log) placements += d["action"] == "place";
  EXPECT_EQ(placements, 2);
}

TEST_F(FloorPlanAlignTest, PointPairsAndAnExplicitPosePlaceThePlanAndBadInputChangesNothing) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  // Nothing to align against yet.
  EXPECT_EQ(send_json("POST", "/api/v1/floorplan/align", json::object(), 409)["error"], "conflict");
  // Bad pairs and bounds: 400, nothing changes.
  const auto version = get_json("/api/v1/map")["version"];
  send_json("POST", "/api/v1/floorplan/pairs", {{"pairs", {{{"plan", {0, 0}}, {"world", {1, 1}}}}}}, 400);
  send_json("POST", "/api/v1/floorplan/pairs",
            {{"pairs", {{{"plan", {0, 0}}, {"world", {1, 1}}}, {{"plan", {0, 0}}, {"world", {1, 1}}}}}}, 400);
  send_json("POST", "/api/v1/floorplan/align", {{"scale", {2, 1}}}, 400);
  send_json("POST", "/api/v1/floorplan/align", {{"scale", {0, 1}}}, 400);
  send_json("POST", "/api/v1/floorplan/place", {{"x", 1}, {"y", 2}, {"theta", 0}, {"scale", -1}}, 400);
  EXPECT_EQ(call("POST", "/api/v1/floorplan/place", R"({"x": 1e999, "y": 0, "theta": 0})").status, 400);
  send_json("PUT", "/api/v1/floorplan/georeference", {{"latitude", 95}, {"longitude", 0}}, 400);
  // Pairs whose plan points nearly coincide would give a scale of 1e11; a far placement; a search over budget.
  send_json("POST", "/api/v1/floorplan/pairs",
            {{"scale", true},
             {"pairs", {{{"plan", {0, 0}}, {"world", {0, 0}}}, {{"plan", {1e-8, 0}}, {"world", {1000, 0}}}}}},
            400);
  send_json("POST", "/api/v1/floorplan/place", {{"x", 1e300}, {"y", 0}, {"theta", 0}}, 400);
  send_json("POST", "/api/v1/floorplan/align", {{"time_budget_ms", 60000}}, 400);
  EXPECT_EQ(get_json("/api/v1/map")["version"], version);

  // Pairs in millimetres: the scale comes out.
  const auto paired = send_json("POST", "/api/v1/floorplan/pairs",
                                {{"scale", true},
                                 {"pairs",
                                  {{{"plan", {0, 0}}, {"world", {10, 20}}},
                                   {{"plan", {1000, 0}}, {"world", {10, 21}}},
                                   {{"plan", {0, 2000}}, {"world", {8, 20}}}}}});
  EXPECT_NEAR(paired["placement"]["scale"].get<double>(), 0.001, 1e-9);
  EXPECT_NEAR(paired["placement"]["theta"].get<double>(), std::numbers::pi / 2, 1e-9);
  EXPECT_NEAR(paired["placement"]["x"].get<double>(), 10, 1e-9);
  // The wall drawn from (0, 10) to (20, 10) is now 10 mm... in the world: turned, scaled, moved.
  const auto wall = get_json("/api/v1/objects/wall-n");
  EXPECT_NEAR(wall["edges"][0]["p0"][0].get<double>(), 10 - 0.010, 1e-9);
  EXPECT_NEAR(wall["edges"][0]["p0"][1].get<double>(), 20, 1e-9);

  const auto placed = send_json("POST", "/api/v1/floorplan/place", {{"x", 1}, {"y", -2}, {"theta_deg", 90}});
  EXPECT_EQ(placed["decision"]["rule"], "plan_placed");
  EXPECT_NEAR(placed["before"]["scale"].get<double>(), 0.001, 1e-9);
  const auto table = get_json("/api/v1/objects/table-1");
  // Drawn at (5, 5), 0.3 rad: placed at (1 - 5, -2 + 5), 0.3 + π/2.
  EXPECT_NEAR(table["pose"]["x"].get<double>(), -4, 1e-9);
  EXPECT_NEAR(table["pose"]["y"].get<double>(), 3, 1e-9);
  EXPECT_NEAR(table["pose"]["theta"].get<double>(), 0.3 + std::numbers::pi / 2, 1e-9);

  // Georeferenced, the GeoJSON export is in longitude/latitude near the origin given.
  send_json("PUT", "/api/v1/floorplan/georeference", {{"latitude", 30.2862}, {"longitude", -97.7365}, {"heading", 90}});
  const auto geo = json::parse(call("GET", "/api/v1/map?format=geojson").body);
  const auto first = geo["features"][0]["geometry"]["coordinates"][0];
  EXPECT_NEAR(first[0].get<double>(), -97.7365, 0.01);
  EXPECT_NEAR(first[1].get<double>(), 30.2862, 0.01);
  EXPECT_NEAR(get_json("/api/v1/floorplan")["georeference"]["latitude"].get<double>(), 30.2862, 1e-12);
  send_json("DELETE", "/api/v1/floorplan/georeference", json::object());
  EXPECT_TRUE(get_json("/api/v1/floorplan")["georeference"].is_null());
}

}  // namespace
}  // namespace wm::testing
