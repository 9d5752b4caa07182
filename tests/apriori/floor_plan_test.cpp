#include "apriori/floor_plan.h"

#include <gtest/gtest.h>

#include <cmath>

namespace wm::apriori {
namespace {

constexpr const char* kLab = R"({
  "name": "lab-2", "units": "m",
  "objects": [
    {"id": "wall-n", "kind": "wall", "attributes": ["solid"], "pose": {"x": 0, "y": 0, "theta": 0},
     "segments": [[[0, 10], [20, 10], [20, 0]]]},
    {"id": "table-1", "kind": "table", "attributes": ["not_deformable"], "pose": {"x": 5, "y": 5, "theta": 0.3},
     "polygon": [[-0.6, -0.4], [0.6, -0.4], [0.6, 0.4], [-0.6, 0.4]]}]})";

std::string error_path(const std::string& text) {
  try {
    parse_floor_plan_json(text);
  } catch (const FloorPlanError& e) {
    return e.path();
  }
  return "<no error>";
}

TEST(FloorPlanTest, ParsesTheDesignExample) {
  const auto plan = parse_floor_plan_json(kLab);
  EXPECT_EQ(plan.name, "lab-2");
  ASSERT_EQ(plan.objects.size(), 2u);
  EXPECT_EQ(plan.objects[0].id, "wall-n");
  EXPECT_TRUE(plan.objects[0].has_attribute("solid"));
  EXPECT_FALSE(plan.objects[0].has_attribute("not_deformable"));
  EXPECT_EQ(plan.objects[0].edges().size(), 2u);  // an open polyline of three points
  EXPECT_DOUBLE_EQ(plan.objects[1].pose.theta_rad, 0.3);
  const auto table_edges = plan.objects[1].edges();
  ASSERT_EQ(table_edges.size(), 4u);  // the polygon is closed implicitly
  EXPECT_EQ(table_edges[3].p0, Eigen::Vector2d(-0.6, 0.4));
  EXPECT_EQ(table_edges[3].p1, Eigen::Vector2d(-0.6, -0.4));
}

TEST(FloorPlanTest, ConvertsCentimetresToMetres) {
  const auto plan = parse_floor_plan_json(
      R"({"units": "cm", "objects": [{"id": "w", "kind": "wall", "pose": {"x": 100, "y": 0, "theta": 0.5},
          "segments": [[[0, 0], [250, 0]]]}]})");
  EXPECT_DOUBLE_EQ(plan.objects[0].pose.x_m, 1.0);
  EXPECT_DOUBLE_EQ(plan.objects[0].pose.theta_rad, 0.5);  // angles stay radians
  EXPECT_DOUBLE_EQ(plan.objects[0].polylines[0][1].x(), 2.5);
}

TEST(FloorPlanTest, CanonicalJsonRoundTripsExactly) {
  auto plan = parse_floor_plan_json(kLab);
  plan.objects[1].pose.x_m = 0.1 + 0.2;  // a value without a short decimal form
  plan.objects[1].pose_cov = Eigen::Vector3d(1e-3, 2e-3, 3e-4).asDiagonal();
  const auto again = parse_floor_plan_json(to_json_text(plan));
  EXPECT_EQ(to_json_text(again), to_json_text(plan));
  EXPECT_EQ(again.objects[1].pose.x_m, plan.objects[1].pose.x_m);
  EXPECT_EQ(*again.objects[1].pose_cov, *plan.objects[1].pose_cov);
}

TEST(FloorPlanTest, ErrorsNameTheBadField) {
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a", "kind": "wall", "pose": {"x": 0, "y": "1", "theta": 0},
                          "segments": [[[0,0],[1,0]]]}]})"),
            "objects[0].pose.y");
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a", "kind": "wall", "segments": [[[0,0],[1e300,0]]]}]})"),
            "objects[0].segments[0][1][0]");
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a", "kind": "wall", "segments": [[[0,0]]]}]})"),
            "objects[0].segments[0]");
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a", "kind": "wall", "segments": [[[0,0],[1,0]]]},
                                        {"id": "a", "kind": "wall", "segments": [[[0,0],[1,0]]]}]})"),
            "objects[1].id");
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a", "kind": "wall"}]})"), "objects[0]");
  EXPECT_EQ(error_path(
                R"({"objects": [{"id": "a", "kind": "wall", "attributes": ["Solid!"], "segments": [[[0,0],[1,0]]]}]})"),
            "objects[0].attributes[0]");
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a", "kind": "wall", "segmnets": [[[0,0],[1,0]]]}]})"),
            "objects[0].segmnets");
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a/b", "kind": "wall", "segments": [[[0,0],[1,0]]]}]})"),
            "objects[0].id");
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a", "kind": "wall", "segments": [[[0,0],[0,0]]]}]})"),
            "objects[0].segments[0][1]");
  EXPECT_EQ(error_path(R"({"units": "ft", "objects": []})"), "units");
  EXPECT_EQ(error_path(R"({"objects": [{"id": "a", "kind": "t", "pose_cov": [[1,0,0],[0,1,0],[0,0,-1]],
                          "polygon": [[0,0],[1,0],[1,1]]}]})"),
            "objects[0].pose_cov");
  EXPECT_EQ(error_path(R"({"objects": {}})"), "objects");
  EXPECT_EQ(error_path(R"({"objects": [)"), "");  // malformed JSON: no field to name
  EXPECT_EQ(error_path(R"([1, 2])"), "");
}

TEST(FloorPlanTest, RejectsTooManyObjects) {
  FloorPlanLimits limits;
  limits.max_objects = 1;
  EXPECT_THROW(parse_floor_plan_json(kLab, limits), FloorPlanError);
}

}  // namespace
}  // namespace wm::apriori
