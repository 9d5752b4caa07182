#pragma once

#include <string>
#include <vector>

#include "apriori/export/layer_lines.h"

namespace wm::apriori {

/// Writes layers of polylines as a GeoJSON (RFC 7946) FeatureCollection: one LineString feature per polyline with
/// properties {"layer": name, "color": ACI colour} plus "id" (and the feature's "id") when ids are given.
/// Coordinates are the plan's world frame in metres, not WGS 84 longitude/latitude: GIS tools must be told to use
/// a local (engineering) CRS. Numbers are written in their shortest round-trip form.
/// @throw std::invalid_argument (message starts "write_geojson:") for a polyline with fewer than 2 points, a
///        non-finite coordinate, or ids that are neither empty nor one per polyline.
std::string write_geojson(const std::vector<LayerLines>& layers);

}  // namespace wm::apriori
