#include "apriori/export/geojson_writer.h"

#include <nlohmann/json.hpp>
#include <stdexcept>

namespace wm::apriori {

std::string write_geojson(const std::vector<LayerLines>& layers) {
  using nlohmann::json;
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
        coordinates.push_back({p.x(), p.y()});
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
  const json collection = {{"type", "FeatureCollection"}, {"features", std::move(features)}};
  return collection.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace wm::apriori
