#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "apriori/import/amrl_import.h"
#include "apriori/import/dxf_import.h"
#include "apriori/import/rmf_import.h"
#include "tests/apriori/plan_test_support.h"

// The real plans shipped in tests/data/plans (see its SOURCE.md). Every expected number below was counted
// independently of the C++ code by tests/apriori/tools/count_real_plans.py (ezdxf, PyYAML, json).

namespace wm::apriori {
namespace {

using test::plans_data_dir;
using test::read_file;

void expect_extent(const ImportReport& r, double x0, double y0, double x1, double y1, double tol) {
  ASSERT_TRUE(r.extent);
  EXPECT_NEAR(r.extent->min_m.x(), x0, tol);
  EXPECT_NEAR(r.extent->min_m.y(), y0, tol);
  EXPECT_NEAR(r.extent->max_m.x(), x1, tol);
  EXPECT_NEAR(r.extent->max_m.y(), y1, tol);
}

std::map<std::string, std::size_t> count_by_kind(const FloorPlan& plan) {
  std::map<std::string, std::size_t> counts;
  for (const auto& o : plan.objects) ++counts[o.kind];
  return counts;
}

TEST(RealPlansTest, BarcelonaPavilionDxfLoadsWithTheDefaultMapping) {
  const auto r = import_dxf(read_file(plans_data_dir() + "/barcelona-pavilion.dxf"), default_layer_mapping());
  const auto& report = r.report;
  EXPECT_EQ(report.version, "AC1027");
  EXPECT_EQ(report.units_to_m, 1.0);
  EXPECT_EQ(report.units_source, "$INSUNITS 6 (metres)");
  EXPECT_EQ(report.entity_counts, (std::map<std::string, std::size_t>{{"LINE", 954}, {"CIRCLE", 188}, {"ARC", 69}}));
  const std::map<std::string, std::size_t> layer_entities{{"Flooring", 260}, {"Walls", 60},  {"Furniture", 450},
                                                          {"Projection", 8}, {"Doors", 118}, {"Crystal", 63},
                                                          {"Cancel", 156},   {"Columns", 96}};
  ASSERT_EQ(report.layers.size(), layer_entities.size());
  for (const auto& [layer, n] : layer_entities) EXPECT_EQ(report.layers.at(layer).entities, n) << layer;
  EXPECT_EQ(report.unknown_layers, (std::vector<std::string>{"Cancel", "Flooring", "Projection"}));
  EXPECT_EQ(report.skipped.at("on unknown layers"), 260u + 156u + 8u);

  // Loose entities clustered into objects: 23 furniture pieces (211 groups of touching entities, of which the
  // cushion buttons and table tops join the piece whose outline encloses them), 7 doors, 8 cruciform columns.
  EXPECT_EQ(report.layers.at("Furniture").objects, 23u);
  EXPECT_EQ(report.layers.at("Doors").objects, 7u);
  EXPECT_EQ(report.layers.at("Columns").objects, 8u);
  EXPECT_EQ(report.clustered_objects, 23u + 7u + 8u);
  EXPECT_EQ(report.layers.at("Walls").objects, 60u);  // one per LINE
  EXPECT_EQ(report.layers.at("Crystal").objects, 63u);
  EXPECT_EQ(report.objects, 161u);
  EXPECT_EQ(r.plan.objects.size(), 161u);
  EXPECT_EQ(count_by_kind(r.plan),
            (std::map<std::string, std::size_t>{{"wall", 123}, {"furniture", 23}, {"door", 7}, {"column", 8}}));
  for (const auto& o : r.plan.objects) {
    if (o.kind == "furniture") {
      EXPECT_TRUE(o.has_attribute("not_deformable")) << o.id;
    }
    if (o.kind == "wall") {
      EXPECT_TRUE(o.has_attribute("solid")) << o.id;
    }
  }
  std::size_t glass = 0;
  for (const auto& o : r.plan.objects) glass += o.has_attribute("glass") ? 1 : 0;
  EXPECT_EQ(glass, 63u);  // the Crystal layer
  EXPECT_EQ(report.skipped.at("paper space"), 1u);

  // Extent of the imported layers (ezdxf's exact bounding box; chords lie inside the arcs by ≤ the tolerance).
  expect_extent(report, 0.0, 0.0, 50.32, 21.42, 0.01);
}

TEST(RealPlansTest, BarcelonaChairIsOneRigidObjectAroundItsCentroid) {
  const auto r = import_dxf(read_file(plans_data_dir() + "/barcelona-pavilion.dxf"), default_layer_mapping());
  std::size_t chairs = 0;
  for (const auto& o : r.plan.objects) {
    if (o.kind != "furniture") continue;
    // Posed at the centroid: the shape is centred on the object frame, so a pose update turns it in place.
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e9), hi = -lo;
    for (const auto& line : test::world_polylines(o))
      for (const auto& w : line) {
        const Eigen::Vector2d p = o.pose.inverse_transform_point(w);
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
    EXPECT_EQ(o.pose.theta_rad, 0.0);
    EXPECT_LT(lo.x(), 0.0);
    EXPECT_GT(hi.x(), 0.0);
    EXPECT_LT(lo.y(), 0.0);
    EXPECT_GT(hi.y(), 0.0);
    // The Barcelona chairs: 6 lines and 42 button circles in a 0.75 m square.
    if (o.polylines.size() == 48 && std::abs(hi.x() - lo.x() - 0.75) < 0.01) ++chairs;
  }
  EXPECT_EQ(chairs, 2u);
}

TEST(RealPlansTest, BarcelonaWithoutEnclosureMergingCountsTouchingGroups) {
  auto mapping = default_layer_mapping();
  mapping.merge_enclosed_clusters = false;
  const auto r = import_dxf(read_file(plans_data_dir() + "/barcelona-pavilion.dxf"), mapping);
  EXPECT_EQ(r.report.layers.at("Furniture").objects, 211u);
  EXPECT_EQ(r.report.layers.at("Doors").objects, 7u);
  EXPECT_EQ(r.report.layers.at("Columns").objects, 8u);
}

TEST(RealPlansTest, RmfOfficeBuildingLoads) {
  const auto r = import_rmf_building(read_file(plans_data_dir() + "/rmf-office.building.yaml"));
  const auto& report = r.report;
  EXPECT_EQ(report.format, "rmf-building");
  EXPECT_EQ(report.version, "L1");
  EXPECT_NEAR(report.units_to_m, 0.008465494911979116, 1e-15);  // mean of the 3 measurements
  EXPECT_EQ(report.units_source, "measurements (3)");
  EXPECT_EQ(report.entity_counts.at("vertices"), 73u);
  EXPECT_EQ(report.entity_counts.at("walls"), 33u);
  EXPECT_EQ(report.entity_counts.at("doors"), 3u);
  EXPECT_EQ(report.entity_counts.at("models"), 79u);
  EXPECT_EQ(report.entity_counts.at("floors"), 4u);
  EXPECT_EQ(report.entity_counts.at("lanes"), 30u);
  EXPECT_EQ(report.skipped.at("model (not static)"), 1u);
  EXPECT_EQ(count_by_kind(r.plan), (std::map<std::string, std::size_t>{{"wall", 33}, {"door", 3}, {"furniture", 78}}));
  std::size_t glass = 0;
  for (const auto& o : r.plan.objects) glass += o.has_attribute("glass") ? 1 : 0;
  EXPECT_EQ(glass, 7u);  // translucent walls (alpha < 1)
  for (const char* id : {"door-main_door", "door-coe_door", "door-hardware_door"})
    EXPECT_NE(test::find_object(r.plan, id), nullptr) << id;
  expect_extent(report, 2.277641406067981, -12.004054854196562, 23.683364858074697, -1.1435613801846989, 1e-9);
}

TEST(RealPlansTest, AmrlVectorMapsLoad) {
  const auto gdc = import_amrl_vectormap(read_file(plans_data_dir() + "/GDC1.vectormap.json"));
  EXPECT_EQ(gdc.report.entity_counts.at("segments"), 1289u);
  EXPECT_EQ(gdc.plan.objects.size(), 1289u);
  expect_extent(gdc.report, -44.462078, -34.467838, 44.462078, 34.467838, 1e-9);
  const auto ahg = import_amrl_vectormap(read_file(plans_data_dir() + "/AHG2.vectormap.json"));
  EXPECT_EQ(ahg.plan.objects.size(), 1270u);
  expect_extent(ahg.report, 0.064262, 22.847918, 81.488022, 77.583855, 1e-9);
  EXPECT_EQ(ahg.plan.objects[0].kind, "wall");
  EXPECT_EQ(ahg.plan.objects[0].attributes, std::vector<std::string>{"solid"});
}

TEST(RealPlansTest, ImportedPlansSurviveTheJsonRoundTrip) {
  const auto r = import_dxf(read_file(plans_data_dir() + "/barcelona-pavilion.dxf"), default_layer_mapping());
  const auto again = parse_floor_plan_json(to_json_text(r.plan));
  EXPECT_EQ(to_json_text(again), to_json_text(r.plan));
}

}  // namespace
}  // namespace wm::apriori
