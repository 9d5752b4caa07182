// GET /api/v1/map: the map as JSON, or as CAD/GIS layers (DXF, GeoJSON); GET /api/v1/map/quality: how good it is.
#include "apriori/export/dxf_writer.h"
#include "apriori/export/geojson_writer.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/service/map_quality_report.h"
#include "server/world/map_layers.h"

namespace wm::api {

Response get_map(const Call& call) {
  const auto snap = call.world.snapshot();
  const auto& options = call.world.world_options();
  const auto format = call.target.param("format").value_or("json");
  const auto bbox = query_bbox(call.target);
  std::optional<world::MapExcerpt> excerpt;
  if (bbox) excerpt = world::map_excerpt(*snap, world::Box{bbox->x0, bbox->y0, bbox->x1, bbox->y1});
  if (format == "json") {
    auto body = json_codec::map_json(*snap, options, excerpt);
    if (bbox) body["bbox"] = {bbox->x0, bbox->y0, bbox->x1, bbox->y1};
    return json_response(call.request, body);
  }
  if (format == "dxf")
    return raw_response(call.request, apriori::write_dxf(world::map_layers(*snap, options, excerpt)), "image/vnd.dxf");
  if (format == "geojson")
    return raw_response(call.request,
                        apriori::write_geojson(world::map_layers(*snap, options, excerpt), snap->georeference),
                        "application/geo+json");
  throw bad_request("format", "expected json, dxf or geojson");
}

Response get_map_quality(const Call& call) {
  const service::MapQualityReportOptions options;
  const auto report = service::measure_map_quality(call.world, options);
  const auto& q = report.map;
  const auto& m = options.map;
  nlohmann::json body{{"map_version", report.map_version},
                      {"grid_revision", report.grid_revision},
                      {"elements", q.elements},
                      {"total_length_m", q.total_length_m},
                      {"median_length_m", q.median_length_m},
                      {"elements_per_m", q.elements_per_m},
                      {"precision", q.precision},
                      {"recall", q.recall},
                      {"redundancy", q.redundancy},
                      {"occupied_cells", q.occupied_cells},
                      {"calibration", report.calibration ? nlohmann::json(*report.calibration) : nlohmann::json()},
                      {"calibration_samples", report.calibration_samples},
                      // What the figures mean, with the numbers they use, so a client need not look them up.
                      {"definitions",
                       {{"precision",
                         "share of element length (sampled every sample_step_m) within one cell of a Bayes-grid cell "
                         "with P > occupied_probability"},
                        {"recall", "share of occupied cells within recall_radius_m of an element"},
                        {"redundancy",
                         "share of element length within redundancy_offset_m and redundancy_angle_deg of another "
                         "element's extent"},
                        {"calibration",
                         "share of the recent scan lines matched to an element whose normalised innovation passes "
                         "the 95 % chi-square gate (5.991); about 0.95 when the covariances are honest"},
                        {"sample_step_m", m.sample_step_m},
                        {"occupied_probability", m.occupied_probability},
                        {"recall_radius_m", m.recall_radius_m},
                        {"redundancy_offset_m", m.redundancy_offset_m},
                        {"redundancy_angle_deg", m.redundancy_angle_rad * 180.0 / 3.14159265358979323846},
                        {"calibration_window_decisions", options.calibration_window}}}};
  return json_response(call.request, body);
}

}  // namespace wm::api
