// Real floor plans through the running wmd: DXF with a layer mapping, Open-RMF, AMRL; export and as-built.
#include <filesystem>
#include <fstream>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

TEST_F(ServerFixture, TheBarcelonaPavilionLoadsWithItsLayersMapped) {
  const auto mapping = dir_.path() / "layers.json";
  std::ofstream(mapping) << R"({"layers": {"Walls": {"kind": "wall", "attributes": ["solid"]},
                                            "Columns": {"kind": "column", "attributes": ["solid"]},
                                            "Crystal": {"kind": "wall", "attributes": ["solid", "glass"]},
                                            "Doors": {"kind": "door", "attributes": ["movable"]},
                                            "Furniture": {"kind": "furniture", "attributes": ["not_deformable"], "cluster": true},
                                            "*": {"ignore": true}}})";
  const auto plan = real_data("barcelona-pavilion/plan.dxf", "plans/barcelona-pavilion.dxf");
  const auto r =
      run_command(wmctl(server_->url(), "--json floorplan load " + plan.string() + " --mapping " + mapping.string()));
  ASSERT_EQ(r.status, 0) << r.output;
  const auto answer = json::parse(r.output);
  const auto& report = answer["report"];
  EXPECT_EQ(report["format"], "dxf");
  EXPECT_TRUE(report["unknown_layers"].empty()) << "everything else is ignored by the mapping";
  EXPECT_EQ(report["layers"]["Furniture"]["status"], "clustered");
  EXPECT_GT(report["clustered_objects"].get<int>(), 5);
  // The mapped layers span 50.32 m × 21.42 m (ezdxf's bbox.extents over the same layers).
  const auto& extent = report["extent"];
  EXPECT_NEAR(extent["max"][0].get<double>() - extent["min"][0].get<double>(), 50.32, 0.02);
  EXPECT_NEAR(extent["max"][1].get<double>() - extent["min"][1].get<double>(), 21.42, 0.02);

  const auto map = get_json("/api/v1/map");
  EXPECT_EQ(map["objects"].size(), answer["objects"].get<std::size_t>());
  std::size_t glass = 0, furniture = 0;
  for (const auto& o : map["objects"]) {
    for (const auto& a : o["attributes"]) glass += a == "glass";
    furniture += o["kind"] == "furniture";
  }
  EXPECT_GT(glass, 0u);
  EXPECT_EQ(furniture, report["layers"]["Furniture"]["objects"].get<std::size_t>());

  // A wall confirmed by an observation shows up in the as-built report; the rest was never observed.
  json wall;
  for (const auto& o : map["objects"])
    if (o["kind"] == "wall" && o["attributes"].size() == 1 && o["edges"][0]["length"].get<double>() > 2.0) {
      wall = o;
      break;
    }
  ASSERT_FALSE(wall.is_null());
  const auto& edge = wall["edges"][0];
  json segment = {{"p0", edge["p0"]}, {"p1", edge["p1"]}};
  const auto decided = send_json("POST", "/api/v1/primitives", {{"segments", {segment}}});
  EXPECT_EQ(decided["decisions"][0]["rule"], "solid_confirmed");
  const auto as_built = get_json("/api/v1/report/as-built");
  EXPECT_EQ(as_built["summary"]["confirmed"], 1);
  EXPECT_EQ(as_built["summary"]["never_observed"], map["objects"].size() - 1);

  // The observed map goes back to CAD and GIS tools.
  const auto dxf = call("GET", "/api/v1/map?format=dxf");
  ASSERT_EQ(dxf.status, 200);
  EXPECT_EQ(dxf.body.rfind("  0\nSECTION", 0), 0u) << dxf.body.substr(0, 40);
  EXPECT_NE(dxf.body.find("confirmed"), std::string::npos);
  const auto geojson = json::parse(call("GET", "/api/v1/map?format=geojson").body);
  EXPECT_EQ(geojson["type"], "FeatureCollection");
  std::size_t edges = 0;
  for (const auto& o : map["objects"]) edges += o["edges"].size();
  EXPECT_EQ(geojson["features"].size(), edges);
}

TEST_F(ServerFixture, RoboticsFloorPlanFormatsLoad) {
  const auto building = real_data("rmf-office/office.building.yaml", "plans/rmf-office.building.yaml");
  auto r = run_command(wmctl(server_->url(), "--json floorplan load " + building.string()));
  ASSERT_EQ(r.status, 0) << r.output;
  auto answer = json::parse(r.output);
  EXPECT_EQ(answer["report"]["format"], "rmf-building");
  EXPECT_GT(answer["objects"].get<int>(), 10);

  // An AMRL vector map is a JSON array of lines: one solid wall per line.
  const auto text = slurp(real_data("amrl-vectormaps/GDC1.vectormap.json", "plans/GDC1.vectormap.json"));
  const auto lines = json::parse(text);
  const auto loaded = send_json("PUT", "/api/v1/floorplan", lines);
  EXPECT_EQ(loaded["report"]["format"], "amrl-vectormap");
  EXPECT_LE(loaded["objects"].get<std::size_t>(), lines.size());
  EXPECT_GT(loaded["objects"].get<std::size_t>(), lines.size() * 9 / 10);
}

TEST_F(ServerFixture, ABadDrawingChangesNothing) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  const auto before = get_json("/api/v1/map");
  const auto dxf = slurp(real_data("barcelona-pavilion/plan.dxf", "plans/barcelona-pavilion.dxf"));
  for (const auto& body :
       {dxf.substr(0, dxf.size() / 2), std::string("AutoCAD Binary DXF\r\n\x1a", 21) + std::string(40, '\0')}) {
    const auto r = call("PUT", "/api/v1/floorplan", body, "image/vnd.dxf");
    EXPECT_EQ(r.status, 400) << r.body.substr(0, 200);
  }
  EXPECT_EQ(get_json("/api/v1/map"), before);
}

}  // namespace
}  // namespace wm::testing
