#include "apriori/export/geojson_writer.h"

#include <nlohmann/json.hpp>
#include <stdexcept>

namespace wm::apriori {
namespace {

// GeoJSON 2008's "crs" member (RFC 7946 dropped it, but GDAL still reads it, as a foreign member) naming an
// engineering CRS: without it GDAL assumes WGS 84 degrees. The axes are "unspecified" because the world frame's
// x, y need not point east and north.
constexpr const char* kLocalCrsWkt =
    "ENGCRS[\"worldmodel world frame\",EDATUM[\"world frame origin (no georeference set)\"],CS[Cartesian,2],"
    "AXIS[\"x\",unspecified,ORDER[1],LENGTHUNIT[\"metre\",1]],"
    "AXIS[\"y\",unspecified,ORDER[2],LENGTHUNIT[\"metre\",1]]]";
constexpr const char* kLocalCoordinates =
    "local metres (x, y) of the world frame, NOT WGS 84 longitude/latitude: no georeference is set";
constexpr const char* kWgs84Coordinates =
    "WGS 84 longitude, latitude [deg] (RFC 7946), from the world frame through the georeference";

}  // namespace

std::string write_geojson(const std::vector<LayerLines>& layers, const std::optional<Georeference>& georeference) {
  using nlohmann::json;
  std::optional<GeoreferenceTransform> transform;
  if (georeference) {
    try {
      transform.emplace(*georeference);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("write_geojson: georeference ") + e.what());
    }
  }
  json features = json::array();
  for (const auto& layer : layers) {
    if (!layer.ids.empty() && layer.ids.size() != layer.polylines.size())
      throw std::invalid_argument("write_geojson: layer '" + layer.layer + "' has ids that are not one per polyline");
    for (std::size_t i = 0; i < layer.polylines.size(); ++i) {
      const auto& line = layer.polylines[i];
      if (line.size() < 2)
        throw std::invalid_argument("write_geojson: polyline " + std::to_string(i) + " of layer '" + layer.layer +
                                    "' has fewer than 2 points");
      json coordinates = json::array();
      for (const auto& p : line) {
        if (!p.allFinite())
          throw std::invalid_argument("write_geojson: polyline " + std::to_string(i) + " of layer '" + layer.layer +
                                      "' has a non-finite coordinate");
        if (transform) {
          const LonLat q = transform->to_lon_lat(p);
          coordinates.push_back({q.longitude_deg, q.latitude_deg});
        } else {
          coordinates.push_back({p.x(), p.y()});
        }
      }
      json properties = {{"layer", layer.layer}, {"color", layer.color}};
      json feature = {{"type", "Feature"},
                      {"geometry", {{"type", "LineString"}, {"coordinates", std::move(coordinates)}}}};
      if (!layer.ids.empty()) {
        properties["id"] = layer.ids[i];
        feature["id"] = layer.ids[i];
      }
      feature["properties"] = std::move(properties);
      features.push_back(std::move(feature));
    }
  }
  json collection = {{"type", "FeatureCollection"}};
  if (georeference) {
    // RFC 7946 §7.1 forbids a member named "coordinates" here, hence "coordinate_system".
    collection["coordinate_system"] = kWgs84Coordinates;
    collection["georeference"] = {{"latitude_deg", georeference->latitude_deg},
                                  {"longitude_deg", georeference->longitude_deg},
                                  {"heading_deg", georeference->heading_deg}};
  } else {
    collection["coordinate_system"] = kLocalCoordinates;
    collection["crs"] = {{"type", "name"}, {"properties", {{"name", kLocalCrsWkt}}}};
  }
  collection["features"] = std::move(features);
  return collection.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace wm::apriori
