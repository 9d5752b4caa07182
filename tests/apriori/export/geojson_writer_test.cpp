#include "apriori/export/geojson_writer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace wm::apriori {
namespace {

/// gtest assertion that `text` contains `part` (the tests do not link gmock's matchers).
::testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << part << "' not found in:\n" << text;
}

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

TEST(GeoJsonWriterTest, WithoutAGeoreferenceItSaysTheCoordinatesAreLocalMetres) {
  const auto j = nlohmann::json::parse(write_geojson({LayerLines{"a", {{{0, 0}, {90, 0}}}}}));
  EXPECT_EQ(j["features"][0]["geometry"]["coordinates"][1][0], 90.0);  // unchanged metres
  EXPECT_TRUE(contains(j["coordinate_system"].get<std::string>(), "local metres"));
  EXPECT_EQ(j["crs"]["type"], "name");
  const auto crs_name = j["crs"]["properties"]["name"].get<std::string>();
  EXPECT_TRUE(crs_name.starts_with("ENGCRS[")) << crs_name;
  EXPECT_FALSE(j.contains("georeference"));
}

TEST(GeoJsonWriterTest, WithAGeoreferenceCoordinatesAreLongitudeLatitude) {
  const Georeference g{45.0, 7.0, 90.0};
  const auto j = nlohmann::json::parse(write_geojson({LayerLines{"a", {{{0, 0}, {1000, 0}}}}}, g));
  const auto& c = j["features"][0]["geometry"]["coordinates"];
  EXPECT_NEAR(c[0][0].get<double>(), 7.0, 1e-12);
  EXPECT_NEAR(c[0][1].get<double>(), 45.0, 1e-12);
  // PROJ's value (see tests/apriori/geo/georeference_test.cpp), written with all its digits: 1e-13° is 1e-8 m.
  EXPECT_NEAR(c[1][0].get<double>(), 7.01268281703984, 1e-13);
  EXPECT_NEAR(c[1][1].get<double>(), 44.9999992957776, 1e-13);
  EXPECT_FALSE(j.contains("crs"));  // RFC 7946: WGS 84 is implied
  EXPECT_TRUE(contains(j["coordinate_system"].get<std::string>(), "WGS 84 longitude, latitude"));
  EXPECT_EQ(j["georeference"]["latitude_deg"], 45.0);
  EXPECT_EQ(j["georeference"]["longitude_deg"], 7.0);
  EXPECT_EQ(j["georeference"]["heading_deg"], 90.0);
}

TEST(GeoJsonWriterTest, BadGeoreferenceNamesTheField) {
  try {
    write_geojson({}, Georeference{91.0, 0.0, 0.0});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_TRUE(std::string(e.what()).starts_with("write_geojson: georeference latitude_deg: expected")) << e.what();
  }
}

}  // namespace
}  // namespace wm::apriori
