#include "apriori/import/dxf_import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "tests/apriori/dxf_text.h"
#include "tests/apriori/plan_test_support.h"

namespace wm::apriori {
namespace {

using test::dxf_block;
using test::dxf_circle;
using test::dxf_file;
using test::dxf_insert;
using test::dxf_line;

constexpr double kPi = 3.14159265358979323846;

LayerMapping mapping(const std::string& extra = "") {
  return parse_layer_mapping_json(R"({"layers": {"W*": {"kind": "wall", "attributes": ["solid"]},
                                                 "F*": {"kind": "furniture", "attributes": ["not_deformable"],
                                                        "cluster": true},
                                                 "IGN": {"ignore": true}},
                                      "blocks": {"T*": {"kind": "table", "attributes": ["not_deformable"]}})" +
                                  extra + "}");
}

FloorPlanError error_of(const std::string& text, const LayerMapping& m = mapping(), const DxfImportOptions& o = {}) {
  try {
    import_dxf(text, m, o);
  } catch (const FloorPlanError& e) {
    return e;
  }
  return FloorPlanError("<no error>", "");
}

TEST(DxfImportTest, OneObjectPerEntityPosedAtItsCentroid) {
  const auto r =
      import_dxf(dxf_file(dxf_line("2F", "Walls", 0, 0, 4, 0) + dxf_circle("30", "Walls", 10, 10, 1)), mapping());
  ASSERT_EQ(r.plan.objects.size(), 2u);
  const auto& wall = r.plan.objects[0];
  EXPECT_EQ(wall.id, "wall-2F");
  EXPECT_EQ(wall.kind, "wall");
  EXPECT_EQ(wall.attributes, std::vector<std::string>{"solid"});
  EXPECT_EQ(wall.pose.x_m, 2.0);
  EXPECT_EQ(wall.pose.theta_rad, 0.0);
  ASSERT_EQ(wall.polylines.size(), 1u);
  EXPECT_EQ(wall.polylines[0][0], Eigen::Vector2d(-2, 0));
  const auto& circle = r.plan.objects[1];
  EXPECT_TRUE(circle.polylines.empty());  // a closed shape alone is the object's polygon
  EXPECT_NEAR(circle.pose.x_m, 10.0, 1e-12);
  EXPECT_NEAR(circle.pose.y_m, 10.0, 1e-12);
  EXPECT_GE(circle.polygon.size(), 8u);
  EXPECT_EQ(r.report.layers.at("Walls").objects, 2u);
  EXPECT_EQ(r.report.layers.at("Walls").status, "mapped");
  ASSERT_TRUE(r.report.extent);
  EXPECT_NEAR(r.report.extent->max_m.x(), 11.0, 1e-12);
  EXPECT_EQ(r.report.extent->min_m, Eigen::Vector2d(0, 0));
}

TEST(DxfImportTest, ArcToleranceBoundsTheChordsDeviation) {
  for (double tol : {0.1, 0.01, 0.001}) {
    DxfImportOptions o;
    o.arc_tolerance_m = tol;
    const auto r = import_dxf(dxf_file(dxf_circle("1", "Walls", 0, 0, 2.0)), mapping(), o);
    const auto& poly = r.plan.objects.at(0).polygon;
    const double half_angle = kPi / static_cast<double>(poly.size());
    const double sagitta = 2.0 * (1.0 - std::cos(half_angle));
    EXPECT_LE(sagitta, tol);
    EXPECT_GT(2.0 * (1.0 - std::cos(kPi / static_cast<double>(poly.size() - 1))), tol * 0.5);  // not wasteful
  }
}

TEST(DxfImportTest, MappedBlockInsertBecomesOneObjectWithItsOwnPose) {
  const auto block = dxf_block("TABLE1", dxf_line("B1", "0", 0, 0, 2, 0) + dxf_line("B2", "0", 2, 0, 2, 1), 1, 0);
  const auto r = import_dxf(dxf_file(dxf_insert("40", "Furn", "table1", 10, 5, 0.5, 90), block), mapping());
  ASSERT_EQ(r.plan.objects.size(), 1u);
  const auto& t = r.plan.objects[0];
  EXPECT_EQ(t.id, "table-40");
  EXPECT_EQ(t.kind, "table");
  EXPECT_EQ(t.pose.x_m, 10.0);
  EXPECT_EQ(t.pose.y_m, 5.0);
  EXPECT_NEAR(t.pose.theta_rad, kPi / 2, 1e-15);
  ASSERT_EQ(t.polylines.size(), 2u);
  // Object frame = block frame scaled, relative to the base point (1, 0).
  EXPECT_NEAR((t.polylines[0][0] - Eigen::Vector2d(-0.5, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((t.polylines[1][1] - Eigen::Vector2d(0.5, 0.5)).norm(), 0.0, 1e-12);
  EXPECT_EQ(r.report.block_objects, 1u);
  EXPECT_EQ(r.report.layers.at("Furn").objects, 1u);  // block objects count on the INSERT's layer
  EXPECT_EQ(r.report.clustered_objects, 0u);
}

TEST(DxfImportTest, LooseEntitiesOfAClusterLayerBecomeOneObjectPerGroup) {
  const auto r = import_dxf(dxf_file(dxf_line("1", "Furn", 0, 0, 1, 0) + dxf_line("2", "Furn", 1, 0, 1, 1) +
                                     dxf_line("3", "Furn", 5, 0, 6, 0) + dxf_circle("4", "Furn", 0.5, 0.5, 0.1) +
                                     dxf_line("5", "Walls", 1.001, 0, 3, 0)),
                            mapping());
  ASSERT_EQ(r.plan.objects.size(), 3u);
  EXPECT_EQ(r.plan.objects[0].id, "wall-5");  // clusters are added after the other objects
  const auto& chair = r.plan.objects[1];
  EXPECT_EQ(chair.id, "furniture-1");
  EXPECT_EQ(chair.polylines.size(), 3u);  // two lines and the enclosed circle (closed: first point repeated)
  EXPECT_EQ(chair.pose.theta_rad, 0.0);
  EXPECT_EQ(r.plan.objects[2].id, "furniture-3");
  EXPECT_EQ(r.report.clustered_objects, 2u);
  EXPECT_EQ(r.report.layers.at("Furn").status, "clustered");
  EXPECT_EQ(r.report.layers.at("Furn").entities, 4u);
  EXPECT_EQ(r.report.layers.at("Furn").objects, 2u);
}

TEST(DxfImportTest, ExpandedBlocksPassTheirLayerToLayerZeroEntities) {
  const auto block = dxf_block("PART", dxf_line("B1", "0", 0, 0, 1, 0) + dxf_line("B2", "Walls", 0, 1, 1, 1) +
                                           dxf_line("B3", "IGN", 0, 2, 1, 2));
  const auto r = import_dxf(
      dxf_file(dxf_insert("50", "Walls2", "PART", 100, 0) + dxf_insert("51", "Other", "PART", 0, 0), block), mapping());
  std::vector<std::string> ids;
  for (const auto& o : r.plan.objects) ids.push_back(o.id);
  EXPECT_EQ(ids, (std::vector<std::string>{"wall-50.B1", "wall-50.B2", "wall-51.B2"}));
  EXPECT_EQ(r.report.unknown_layers, std::vector<std::string>{"Other"});
  EXPECT_EQ(r.report.skipped.at("on unknown layers"), 1u);  // B1 of insert 51, on layer Other
  EXPECT_EQ(r.report.skipped.at("on ignored layers"), 2u);
  EXPECT_EQ(r.report.block_inserts, 2u);
}

TEST(DxfImportTest, FilesWithoutHandlesGetIdsFromLineNumbers) {
  const auto r = import_dxf(dxf_file(dxf_line("", "Walls", 0, 0, 1, 0)), mapping());
  EXPECT_EQ(r.plan.objects.at(0).id, "wall-L25");
}

TEST(DxfImportTest, ABlockThatInsertsItselfIsRefused) {
  const auto direct = dxf_block("A", dxf_line("A1", "0", 0, 0, 1, 0) + dxf_insert("A2", "0", "a", 1, 0));
  auto e = error_of(dxf_file(dxf_insert("1", "Walls", "A", 0, 0), direct));
  EXPECT_EQ(e.path(), "block A > entity INSERT handle A2");
  EXPECT_NE(std::string(e.what()).find("inserts itself (A → A)"), std::string::npos) << e.what();

  const auto indirect = dxf_block("A", dxf_insert("A1", "0", "B", 0, 0)) +
                        dxf_block("B", dxf_insert("B1", "0", "C", 0, 0)) +
                        dxf_block("C", dxf_insert("C1", "0", "A", 0, 0));
  e = error_of(dxf_file(dxf_line("1", "Walls", 0, 0, 1, 0), indirect));  // even when no INSERT uses it
  EXPECT_EQ(e.path(), "block C > entity INSERT handle C1");
  EXPECT_NE(std::string(e.what()).find("(A → B → C → A)"), std::string::npos) << e.what();
}

TEST(DxfImportTest, AbsurdCoordinatesAreRefusedWithTheEntity) {
  EXPECT_EQ(error_of(dxf_file(dxf_line("2F", "Walls", 0, 0, 2e5, 0))).path(), "entity LINE handle 2F");
  // In range in the file, absurd in metres: 2e8 mm = 200 km.
  const std::string mm = "  9\n$INSUNITS\n 70\n4\n";
  EXPECT_EQ(error_of(dxf_file(dxf_line("30", "Walls", 0, 0, 2e8, 0), "", mm)).path(), "entity LINE handle 30");
  EXPECT_NO_THROW(import_dxf(dxf_file(dxf_line("31", "Walls", 0, 0, 2e7, 0), "", mm), mapping()));
  // Absurd through a block's scale.
  const auto e =
      error_of(dxf_file(dxf_insert("40", "Walls", "P", 0, 0, 1e6), dxf_block("P", dxf_line("P1", "0", 0, 0, 1, 0))));
  EXPECT_EQ(e.path(), "entity INSERT handle 40 > entity LINE handle P1");
  // The limit is the plan's (as for JSON plans).
  DxfImportOptions o;
  o.limits.max_abs_coordinate_m = 10.0;
  EXPECT_EQ(error_of(dxf_file(dxf_line("32", "Walls", 0, 0, 11, 0)), mapping(), o).path(), "entity LINE handle 32");
}

TEST(DxfImportTest, UnknownLayerPolicies) {
  const auto text = dxf_file(dxf_line("1", "Walls", 0, 0, 1, 0) + dxf_line("2", "Mystery", 0, 0, 1, 0));
  EXPECT_EQ(import_dxf(text, mapping()).report.unknown_layers, std::vector<std::string>{"Mystery"});
  const auto ignored = import_dxf(text, mapping(R"(, "unknown_layers": "ignore")"));
  EXPECT_TRUE(ignored.report.unknown_layers.empty());
  EXPECT_EQ(ignored.report.layers.at("Mystery").status, "unknown");
  EXPECT_EQ(ignored.plan.objects.size(), 1u);
  EXPECT_EQ(error_of(text, mapping(R"(, "unknown_layers": "error")")).path(), "layer Mystery");
}

TEST(DxfImportTest, UndefinedBlocksAreSkippedWithAWarning) {
  const auto r = import_dxf(dxf_file(dxf_insert("1", "Walls", "GHOST", 0, 0) + dxf_insert("2", "Walls", "ghost", 0, 0)),
                            mapping());
  EXPECT_EQ(r.report.skipped.at("INSERT of undefined block"), 2u);
  ASSERT_EQ(r.report.warnings.size(), 2u);  // once for the block, once for the empty plan
  EXPECT_NE(r.report.warnings[0].find("GHOST"), std::string::npos);
}

TEST(DxfImportTest, DegenerateEntitiesAreSkippedAndCounted) {
  const std::string arc = "  0\nARC\n  5\nA1\n  8\nWalls\n 10\n0\n 20\n0\n 40\n1\n 50\n30\n 51\n30\n";
  const std::string full = "  0\nARC\n  5\nA2\n  8\nWalls\n 10\n0\n 20\n0\n 40\n1\n 50\n0\n 51\n360\n";
  const std::string point = "  0\nLWPOLYLINE\n  5\nP1\n  8\nFurn\n 90\n1\n 10\n3\n 20\n3\n";
  const auto r = import_dxf(dxf_file(arc + full + point + dxf_line("L1", "Walls", 1, 1, 1, 1 + 1e-9)), mapping());
  EXPECT_EQ(r.report.skipped.at("degenerate ARC"), 1u);         // equal angles: nothing (as ezdxf reads it)
  EXPECT_EQ(r.report.skipped.at("degenerate LWPOLYLINE"), 1u);  // one vertex
  EXPECT_EQ(r.report.skipped.at("degenerate LINE"), 1u);        // shorter than 1e-6 m
  ASSERT_EQ(r.plan.objects.size(), 1u);                         // 0° → 360°: the whole circle
  EXPECT_EQ(r.plan.objects[0].id, "wall-A2");
  EXPECT_GE(r.plan.objects[0].polylines.at(0).size(), 9u);
}

TEST(DxfImportTest, UnitOverrideWinsOverInsunits) {
  DxfImportOptions o;
  o.units_to_m = 0.001;
  const auto r = import_dxf(dxf_file(dxf_line("1", "Walls", 0, 0, 1000, 0)), mapping(), o);
  EXPECT_EQ(r.report.units_to_m, 0.001);
  EXPECT_EQ(r.report.units_source, "override");
  EXPECT_EQ(r.plan.objects[0].polylines[0][1].x(), 0.5);
}

TEST(DxfImportTest, DeeplyExpandingDrawingsAreRefused) {
  // Each level inserts the next one 10 times: 10^7 lines from a few hundred bytes.
  std::string blocks;
  for (int level = 0; level < 7; ++level) {
    std::string inserts;
    for (int k = 0; k < 10; ++k)
      inserts +=
          dxf_insert("L" + std::to_string(level) + "K" + std::to_string(k), "0", "B" + std::to_string(level + 1), k, 0);
    blocks += dxf_block("B" + std::to_string(level), inserts);
  }
  blocks += dxf_block("B7", dxf_line("X", "0", 0, 0, 0.001, 0));
  DxfImportOptions o;
  o.max_total_points = 100000;
  const auto e = error_of(dxf_file(dxf_insert("1", "Walls", "B0", 0, 0), blocks), mapping(), o);
  EXPECT_NE(std::string(e.what()).find("expands to more than"), std::string::npos) << e.what();
}

TEST(DxfImportTest, OptionsOutOfRangeAreInvalidArguments) {
  DxfImportOptions o;
  o.units_to_m = 0.0;
  EXPECT_THROW(import_dxf(dxf_file(""), mapping(), o), std::invalid_argument);
  o = {};
  o.arc_tolerance_m = std::nan("");
  EXPECT_THROW(import_dxf(dxf_file(""), mapping(), o), std::invalid_argument);
}

TEST(DxfImportTest, ReportIsJson) {
  const auto r =
      import_dxf(dxf_file(dxf_line("1", "Walls", 0, 0, 1, 0) + dxf_line("2", "M\xF6", 0, 0, 1, 0)), mapping());
  const auto j = nlohmann::json::parse(to_json_text(r.report));
  EXPECT_EQ(j["format"], "dxf");
  EXPECT_EQ(j["objects"], 1);
  EXPECT_EQ(j["entity_counts"]["LINE"], 2);
  EXPECT_EQ(j["unknown_layers"][0], "Mö");
  EXPECT_EQ(j["extent"]["max"][0], 1.0);
  EXPECT_EQ(j["layers"]["Walls"]["status"], "mapped");
}

}  // namespace
}  // namespace wm::apriori
