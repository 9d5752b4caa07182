#include "apriori/export/geojson_writer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace wm::apriori {
namespace {

TEST(GeoJsonWriterTest, WritesAFeatureCollectionOfLineStrings) {
  LayerLines confirmed{"confirmed", {{{0.0, 0.0}, {1.0 / 3.0, 2.5}}, {{1, 1}, {2, 1}, {2, 2}}}};
  confirmed.ids = {"wall-1", "wall-2"};
  confirmed.color = 3;
  const LayerLines added{"new", {{{5, 5}, {6, 5}}}};
  const auto j = nlohmann::json::parse(write_geojson({confirmed, added}));
  EXPECT_EQ(j["type"], "FeatureCollection");
  ASSERT_EQ(j["features"].size(), 3u);
  const auto& f = j["features"][0];
  EXPECT_EQ(f["type"], "Feature");
  EXPECT_EQ(f["id"], "wall-1");
  EXPECT_EQ(f["geometry"]["type"], "LineString");
  EXPECT_EQ(f["geometry"]["coordinates"][1][0].get<double>(), 1.0 / 3.0);  // shortest round-trip form
  EXPECT_EQ(f["properties"]["layer"], "confirmed");
  EXPECT_EQ(f["properties"]["color"], 3);
  EXPECT_EQ(f["properties"]["id"], "wall-1");
  EXPECT_EQ(j["features"][1]["geometry"]["coordinates"].size(), 3u);
  EXPECT_FALSE(j["features"][2].contains("id"));
  EXPECT_EQ(j["features"][2]["properties"]["layer"], "new");
}

TEST(GeoJsonWriterTest, EmptyInputIsAnEmptyCollection) {
  const auto j = nlohmann::json::parse(write_geojson({}));
  EXPECT_TRUE(j["features"].empty());
}

TEST(GeoJsonWriterTest, BadInputIsAnInvalidArgument) {
  EXPECT_THROW(write_geojson({LayerLines{"a", {{{0, 0}}}}}), std::invalid_argument);
  EXPECT_THROW(write_geojson({LayerLines{"a", {{{0, 0}, {INFINITY, 1}}}}}), std::invalid_argument);
  LayerLines ids{"a", {{{0, 0}, {1, 1}}}};
  ids.ids = {"x", "y"};
  EXPECT_THROW(write_geojson({ids}), std::invalid_argument);
}

}  // namespace
}  // namespace wm::apriori
