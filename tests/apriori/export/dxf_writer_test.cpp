#include "apriori/export/dxf_writer.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "apriori/dxf/dxf_reader.h"
#include "apriori/import/dxf_import.h"

namespace wm::apriori {
namespace {

std::vector<LayerLines> sample() {
  LayerLines confirmed{"confirmed",
                       {{{0.0, 0.0}, {10.0, 0.0}}, {{0.1, 0.2}, {1.0 / 3.0, 2.0 / 3.0}, {-5e-7, 123456.789}}}};
  confirmed.color = 3;
  LayerLines adjusted{"adjusted objects", {{{1, 1}, {2, 1}, {2, 2}, {1, 2}, {1, 1}}}};  // closed: first point repeated
  adjusted.ids = {"table-1"};
  return {confirmed, adjusted, LayerLines{"new", {}}};
}

/// Runs the ezdxf reader script on `dxf` and returns its JSON answer.
nlohmann::json read_with_ezdxf(const std::string& dxf) {
  const auto path =
      std::filesystem::temp_directory_path() / ("wm_dxf_writer_test_" + std::to_string(::getpid()) + ".dxf");
  {
    std::ofstream out(path, std::ios::binary);
    out << dxf;
  }
  const std::string command =
      std::string(WM_APRIORI_PYTHON) + " " + WM_APRIORI_TOOLS_DIR + "/read_dxf_with_ezdxf.py " + path.string();
  FILE* pipe = ::popen(command.c_str(), "r");
  if (!pipe) throw std::runtime_error("cannot run " + command);
  std::string output;
  char buffer[4096];
  while (std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) output.append(buffer, n);
  const int status = ::pclose(pipe);
  std::filesystem::remove(path);
  if (status != 0)
    throw std::runtime_error(command + " failed (status " + std::to_string(status) + "): is python3-ezdxf installed?");
  return nlohmann::json::parse(output);
}

TEST(DxfWriterTest, OurReaderReadsTheExactCoordinatesBack) {
  const auto doc = dxf::read_dxf(write_dxf(sample()));
  EXPECT_EQ(doc.version, "AC1009");
  EXPECT_EQ(*doc.insunits, 6);
  ASSERT_EQ(doc.entities.size(), 3u);
  EXPECT_EQ(doc.entities[0].type, "LINE");
  EXPECT_EQ(doc.entities[0].layer, "confirmed");
  const auto& poly = std::get<dxf::Polyline>(doc.entities[1].shape);
  ASSERT_EQ(poly.vertices.size(), 3u);
  EXPECT_EQ(poly.vertices[1].point, Eigen::Vector2d(1.0 / 3.0, 2.0 / 3.0));  // bit for bit
  EXPECT_EQ(poly.vertices[2].point, Eigen::Vector2d(-5e-7, 123456.789));
  EXPECT_FALSE(poly.closed);
  const auto& square = std::get<dxf::Polyline>(doc.entities[2].shape);
  EXPECT_EQ(doc.entities[2].layer, "adjusted_objects");
  EXPECT_TRUE(square.closed);
  EXPECT_EQ(square.vertices.size(), 4u);
}

TEST(DxfWriterTest, ExportedMapImportsAgainWithTheSameGeometry) {
  auto mapping = parse_layer_mapping_json(R"({"layers": {"*": {"kind": "wall"}}})");
  DxfImportOptions o;
  o.limits.max_abs_coordinate_m = 1e6;
  const auto r = import_dxf(write_dxf(sample()), mapping, o);
  ASSERT_EQ(r.plan.objects.size(), 3u);
  const auto& square = r.plan.objects[2];
  ASSERT_EQ(square.polygon.size(), 4u);
  EXPECT_EQ(square.pose.transform_point(square.polygon[2]), Eigen::Vector2d(2, 2));
}

TEST(DxfWriterTest, EzdxfReadsTheOutputWithoutAuditErrors) {
  const auto j = read_with_ezdxf(write_dxf(sample()));
  EXPECT_EQ(j["version"], "AC1009");
  EXPECT_EQ(j["audit_errors"], 0);
  EXPECT_EQ(j["insunits"], 6);  // metres, also in R12
  EXPECT_EQ(j["layers"]["confirmed"], 3);
  EXPECT_EQ(j["layers"]["new"], 7);
  ASSERT_EQ(j["entities"].size(), 3u);
  EXPECT_EQ(j["entities"][0]["type"], "LINE");
  EXPECT_EQ(j["entities"][1]["type"], "POLYLINE");
  EXPECT_EQ(j["entities"][1]["points"][1][0].get<double>(), 1.0 / 3.0);  // exact through a foreign reader too
  EXPECT_EQ(j["entities"][1]["points"][2][1].get<double>(), 123456.789);
  EXPECT_EQ(j["entities"][2]["closed"], true);
  EXPECT_EQ(j["entities"][2]["layer"], "adjusted_objects");
  EXPECT_EQ(j["entities"][2]["points"].size(), 4u);
}

TEST(DxfWriterTest, LayerNamesAreMadeValidForR12) {
  EXPECT_EQ(dxf_layer_name("state: new/merged"), "state__new_merged");
  EXPECT_EQ(dxf_layer_name(std::string(40, 'A')).size(), 31u);
  EXPECT_EQ(dxf_layer_name("WALL-$1_x"), "WALL-$1_x");
}

TEST(DxfWriterTest, BadInputIsAnInvalidArgument) {
  EXPECT_THROW(write_dxf({LayerLines{"a", {{{0, 0}}}}}), std::invalid_argument);
  EXPECT_THROW(write_dxf({LayerLines{"a", {{{0, 0}, {std::nan(""), 1}}}}}), std::invalid_argument);
  EXPECT_THROW(write_dxf({LayerLines{"", {{{0, 0}, {1, 1}}}}}), std::invalid_argument);
  LayerLines colour{"a", {{{0, 0}, {1, 1}}}};
  colour.color = 0;
  EXPECT_THROW(write_dxf({colour}), std::invalid_argument);
  LayerLines ids{"a", {{{0, 0}, {1, 1}}}};
  ids.ids = {"x", "y"};
  EXPECT_THROW(write_dxf({ids}), std::invalid_argument);
}

TEST(DxfWriterTest, EmptyInputIsAValidDrawing) {
  const auto doc = dxf::read_dxf(write_dxf({}));
  EXPECT_TRUE(doc.entities.empty());
}

}  // namespace
}  // namespace wm::apriori
