#include "apriori/import/rmf_import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace wm::apriori {
namespace {

// 100 px = 2 m (measurement between vertices 0 and 1), y down in the image.
constexpr const char* kBuilding = R"(
coordinate_system: reference_image
levels:
  L2:
    elevation: 3
    vertices: []
  L1:
    elevation: 0
    vertices:
      - [0, 0, 0, ""]
      - [100, 0, 0, ""]
      - [100, 50, 0, "corner"]
      - [0, 50, 0, ""]
    measurements:
      - [0, 1, {distance: [3, 2.0]}]
    walls:
      - [0, 1, {alpha: [3, 1], texture_name: [1, wall_white]}]
      - [1, 2, {alpha: [3, 0.5]}]
      - [2, 2, {}]
    doors:
      - [2, 3, {name: [1, front/door], type: [1, hinged]}]
    models:
      - {model_name: OpenRobotics/AdjTable, name: AdjTable, static: true, x: 50, y: 25, yaw: 0.5, z: 0}
      - {model_name: OpenRobotics/AdjTable, name: AdjTable, static: true, x: 10, y: 10, yaw: 0, z: 0}
      - {model_name: MiR100, name: robot, static: false, x: 10, y: 10, yaw: 0, z: 0}
      - {model_name: OpenRobotics/TrashBin, name: bin, x: 20, y: 20, yaw: 0}
)";

std::string error_path(const std::string& text, const RmfImportOptions& o = {}) {
  try {
    import_rmf_building(text, o);
  } catch (const FloorPlanError& e) {
    return e.path();
  }
  return "<no error>";
}

TEST(RmfImportTest, ScalesPixelsByMeasurementsAndFlipsY) {
  const auto r = import_rmf_building(kBuilding);
  EXPECT_EQ(r.report.version, "L1");  // the lowest level; the report says so
  ASSERT_FALSE(r.report.warnings.empty());
  EXPECT_EQ(r.report.units_to_m, 0.02);
  const auto& wall = r.plan.objects.at(1);  // vertex 1 → 2: (2, 0) → (2, -1) m
  EXPECT_EQ(wall.id, "wall-1");
  EXPECT_EQ(wall.kind, "wall");
  EXPECT_EQ(wall.attributes, (std::vector<std::string>{"solid", "glass"}));  // alpha 0.5
  EXPECT_EQ(wall.pose.transform_point(wall.polylines[0][1]), Eigen::Vector2d(2, -1));
  EXPECT_EQ(r.report.skipped.at("degenerate wall"), 1u);
  const auto& door = r.plan.objects.at(2);
  EXPECT_EQ(door.id, "door-front_door");
  EXPECT_EQ(door.attributes, std::vector<std::string>{"movable"});
}

TEST(RmfImportTest, ModelsBecomeRectanglesPosedWithTheirYaw) {
  RmfImportOptions o;
  o.model_sizes = {{"*AdjTable", {1.6, 0.8}}};
  o.model_rules = {{"*AdjTable", false, "table", {"not_deformable"}, false}, {"*Trash*", true, "", {}, false}};
  const auto r = import_rmf_building(kBuilding, o);
  ASSERT_EQ(r.plan.objects.size(), 2u + 1u + 2u);
  const auto& table = r.plan.objects[3];
  EXPECT_EQ(table.id, "AdjTable");
  EXPECT_EQ(r.plan.objects[4].id, "AdjTable-2");
  EXPECT_EQ(table.kind, "table");
  EXPECT_EQ(table.pose.x_m, 1.0);
  EXPECT_EQ(table.pose.y_m, -0.5);
  EXPECT_EQ(table.pose.theta_rad, 0.5);
  ASSERT_EQ(table.polygon.size(), 4u);
  EXPECT_NEAR((table.polygon[2] - Eigen::Vector2d(0.8, 0.4)).norm(), 0.0, 1e-12);
  EXPECT_EQ(r.report.skipped.at("model (not static)"), 1u);
  EXPECT_EQ(r.report.skipped.at("model (ignored)"), 1u);
}

TEST(RmfImportTest, ErrorsNameTheYamlPath) {
  RmfImportOptions l1;
  l1.level = "L1";
  EXPECT_EQ(error_path("levels: {L1: {vertices: [[0, 0, 0, a]], walls: [[0, 7, {}]], measurements: []}}", l1),
            "levels.L1.measurements");
  RmfImportOptions scale;
  scale.metres_per_pixel = 0.01;
  EXPECT_EQ(error_path("levels: {L1: {vertices: [[0, 0, 0, a]], walls: [[0, 7, {}]]}}", scale),
            "levels.L1.walls[0][1]");
  EXPECT_EQ(error_path("levels: {L1: {vertices: [[0, x, 0, a]]}}", scale), "levels.L1.vertices[0][1]");
  EXPECT_EQ(error_path("levels: {L1: {vertices: [[0, 1e12, 0, a], [0, 0, 0, b]], walls: [[0, 1, {}]]}}", scale),
            "levels.L1.walls[0]");  // absurd coordinate
  RmfImportOptions missing;
  missing.level = "L9";
  EXPECT_EQ(error_path(kBuilding, missing), "levels");
  EXPECT_EQ(error_path("coordinate_system: wgs84\nlevels: {}"), "coordinate_system");
  EXPECT_EQ(error_path("levels: [1, 2"), "line 1");
  EXPECT_EQ(error_path("- 1\n- 2\n"), "");
  // A model name that is not UTF-8 (found by fuzz_rmf: it escaped as nlohmann's type_error 316).
  EXPECT_EQ(error_path("levels:\n  L1: {models: [{model_name: t\xff, name: t\xff}]}\n", scale), "line 2");
}

TEST(RmfImportTest, NamesThatAreNotUtf8AfterUnescapingAreRefused) {
  // Found by fuzz_rmf: the text is UTF-8, but yaml-cpp reads the NUL in this flow-sequence scalar back as a lone
  // byte 0xA0, which escaped as nlohmann's type_error 316 when the plan was written as JSON.
  using namespace std::string_literals;
  const std::string yaml =
      "levels:\n  L1:\n    vertices: [[0, 0, 0, a], [100, 0, 0, b]]\n"
      "    doors:\n      - [0, 1, {name: [1, ma \0_door], motion_axis: [1, start]}]\n"s;
  RmfImportOptions scale;
  scale.metres_per_pixel = 0.01;
  try {
    import_rmf_building(yaml, scale);
    FAIL() << "accepted";
  } catch (const FloorPlanError& e) {
    EXPECT_NE(std::string(e.what()).find("not UTF-8 after unescaping"), std::string::npos) << e.what();
  }
}

TEST(RmfImportTest, CartesianMetresAreUsedAsTheyAre) {
  const auto r = import_rmf_building(
      "coordinate_system: cartesian_meters\nlevels: {L1: {vertices: [[1, 2, 0, a], [3, 2, 0, b]], walls: [[0, 1, "
      "{}]]}}");
  EXPECT_EQ(r.report.units_to_m, 1.0);
  EXPECT_EQ(r.plan.objects[0].pose.y_m, 2.0);
}

TEST(RmfImportTest, OptionsOutOfRangeAreInvalidArguments) {
  RmfImportOptions o;
  o.metres_per_pixel = -1.0;
  EXPECT_THROW(import_rmf_building(kBuilding, o), std::invalid_argument);
  o = {};
  o.default_model_size_m = {0.0, 1.0};
  EXPECT_THROW(import_rmf_building(kBuilding, o), std::invalid_argument);
}

}  // namespace
}  // namespace wm::apriori
