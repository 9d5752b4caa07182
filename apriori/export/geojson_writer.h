#pragma once

#include <optional>
#include <string>
#include <vector>

#include "apriori/export/layer_lines.h"
#include "apriori/geo/georeference.h"

namespace wm::apriori {

/// Writes layers of polylines (world frame [m]) as a GeoJSON FeatureCollection: one LineString feature per
/// polyline with properties {"layer": name, "color": ACI colour} plus "id" (and the feature's "id") when ids are
/// given. Numbers are written in their shortest round-trip form (for degrees about 1e-14°, i.e. nanometres).
///
/// With a georeference, the coordinates are WGS 84 [longitude, latitude] in degrees, as RFC 7946 requires (see
/// GeoreferenceTransform), and the collection carries the georeference as a foreign member "georeference"
/// {latitude_deg, longitude_deg, heading_deg}.
/// Without one, the coordinates stay local metres of the world frame, which every RFC 7946 reader would take for
/// degrees (GDAL did: a 90 m building 90° wide). So the collection then carries the 2008 GeoJSON "crs" member
/// naming a local engineering CRS as WKT2 (GDAL, and through it QGIS, reads it: ENGCRS, metres, and refuses to
/// reproject it to WGS 84), and both forms carry a plain foreign member "coordinate_system" saying in words
/// which coordinates these are.
/// @throw std::invalid_argument (message starts "write_geojson:") for a polyline with fewer than 2 points, a
///        non-finite coordinate, ids that are neither empty nor one per polyline, or a georeference that fails
///        validate() (the message then names the field).
std::string write_geojson(const std::vector<LayerLines>& layers,
                          const std::optional<Georeference>& georeference = std::nullopt);

}  // namespace wm::apriori
