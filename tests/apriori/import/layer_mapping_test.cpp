#include "apriori/import/layer_mapping.h"

#include <gtest/gtest.h>

#include "apriori/floor_plan.h"

namespace wm::apriori {
namespace {

std::string error_path(const std::string& text) {
  try {
    parse_layer_mapping_json(text);
  } catch (const FloorPlanError& e) {
    return e.path();
  }
  return "<no error>";
}

TEST(LayerMappingTest, GlobMatchesWholeNamesCaseInsensitively) {
  EXPECT_TRUE(glob_match("WALL*", "Walls"));
  EXPECT_TRUE(glob_match("WALL*", "wall"));
  EXPECT_FALSE(glob_match("WALL*", "A-WALL"));
  EXPECT_TRUE(glob_match("*WALL*", "A-WALL-EXT"));
  EXPECT_TRUE(glob_match("A-?ALL", "a-wall"));
  EXPECT_FALSE(glob_match("A-?ALL", "A-ALL"));
  EXPECT_TRUE(glob_match("*", ""));
  EXPECT_FALSE(glob_match("", "x"));
  EXPECT_TRUE(glob_match("0", "0"));
  EXPECT_TRUE(glob_match("*a*b*c", "xaxxbxxxc"));
  EXPECT_FALSE(glob_match("*a*b*c", "xaxxbxxxcx"));
  EXPECT_TRUE(glob_match("Möbel*", "Möbel-1"));  // UTF-8 bytes compare as they are
}

TEST(LayerMappingTest, ParsesTheBriefExampleAndFirstMatchWinsInFileOrder) {
  const auto m = parse_layer_mapping_json(R"({
    "layers": {"WALL*": {"kind": "wall", "attributes": ["solid"]},
               "FURN*": {"kind": "furniture", "attributes": ["not_deformable"], "cluster": true},
               "Crystal": {"kind": "wall", "attributes": ["solid", "glass"]},
               "C*": {"kind": "column"},
               "0": {"ignore": true}},
    "blocks": {"TABLE*": {"kind": "table", "attributes": ["not_deformable"]}},
    "cluster_tolerance_m": 0.05, "merge_enclosed_clusters": false, "unknown_layers": "error"})");
  ASSERT_EQ(m.layers.size(), 5u);
  EXPECT_EQ(m.layers[0].pattern, "WALL*");  // the JSON order, not alphabetical
  EXPECT_EQ(m.layers[1].pattern, "FURN*");
  EXPECT_EQ(m.match_layer("crystal")->kind, "wall");  // before "C*"
  EXPECT_EQ(m.match_layer("Crystal")->attributes, (std::vector<std::string>{"solid", "glass"}));
  EXPECT_EQ(m.match_layer("Columns")->kind, "column");
  EXPECT_TRUE(m.match_layer("FURNITURE")->cluster);
  EXPECT_TRUE(m.match_layer("0")->ignore);
  EXPECT_EQ(m.match_layer("Flooring"), nullptr);
  EXPECT_EQ(m.match_block("table_round")->kind, "table");
  EXPECT_EQ(m.match_block("Chair"), nullptr);
  EXPECT_EQ(m.cluster_tolerance_m, 0.05);
  EXPECT_FALSE(m.merge_enclosed_clusters);
  EXPECT_EQ(m.unknown_layers, UnknownLayerPolicy::kError);
}

TEST(LayerMappingTest, DefaultsAreDocumented) {
  const auto m = parse_layer_mapping_json("{}");
  EXPECT_TRUE(m.layers.empty());
  EXPECT_EQ(m.cluster_tolerance_m, 0.02);
  EXPECT_TRUE(m.merge_enclosed_clusters);
  EXPECT_EQ(m.unknown_layers, UnknownLayerPolicy::kReport);
}

TEST(LayerMappingTest, DefaultMappingFitsTheBarcelonaLayers) {
  const auto m = default_layer_mapping();
  EXPECT_EQ(m.match_layer("Walls")->attributes, std::vector<std::string>{"solid"});
  EXPECT_EQ(m.match_layer("Crystal")->attributes, (std::vector<std::string>{"solid", "glass"}));
  EXPECT_TRUE(m.match_layer("Furniture")->cluster);
  EXPECT_EQ(m.match_layer("Furniture")->attributes, std::vector<std::string>{"not_deformable"});
  EXPECT_EQ(m.match_layer("Doors")->kind, "door");
  EXPECT_EQ(m.match_layer("Columns")->kind, "column");
  EXPECT_TRUE(m.match_layer("Defpoints")->ignore);
  EXPECT_EQ(m.match_layer("Flooring"), nullptr);
  EXPECT_EQ(m.match_block("TABLE-1")->kind, "table");
  EXPECT_EQ(parse_layer_mapping_json(default_layer_mapping_json()).layers.size(), m.layers.size());
}

TEST(LayerMappingTest, ErrorsNameTheBadField) {
  EXPECT_EQ(error_path(R"({"layers": {"W*": {"kind": "wall", "attributes": ["solid", "Not An Atom"]}}})"),
            "layers.W*.attributes[1]");
  EXPECT_EQ(error_path(R"({"layers": {"W*": {"attributes": ["solid"]}}})"), "layers.W*.kind");
  EXPECT_EQ(error_path(R"({"layers": {"W*": {"kind": "wall", "clutser": true}}})"), "layers.W*.clutser");
  EXPECT_EQ(error_path(R"({"layers": {"W*": {"ignore": true, "kind": "wall"}}})"), "layers.W*");
  EXPECT_EQ(error_path(R"({"layers": {"W*": {"kind": ""}}})"), "layers.W*.kind");
  EXPECT_EQ(error_path(R"({"layers": {"W*": {"kind": "a/b"}}})"), "layers.W*.kind");
  EXPECT_EQ(error_path(R"({"layers": {"": {"kind": "wall"}}})"), "layers.");
  EXPECT_EQ(error_path(R"({"blocks": {"T*": {"kind": "table", "cluster": true}}})"), "blocks.T*.cluster");
  EXPECT_EQ(error_path(R"({"layers": []})"), "layers");
  EXPECT_EQ(error_path(R"({"cluster_tolerance_m": 0})"), "cluster_tolerance_m");
  EXPECT_EQ(error_path(R"({"cluster_tolerance_m": "1"})"), "cluster_tolerance_m");
  EXPECT_EQ(error_path(R"({"unknown_layers": "maybe"})"), "unknown_layers");
  EXPECT_EQ(error_path(R"({"layer": {}})"), "layer");
  EXPECT_EQ(error_path(R"({"layers": )"), "");
  EXPECT_EQ(error_path(R"([])"), "");
}

}  // namespace
}  // namespace wm::apriori
