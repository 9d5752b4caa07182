// GET /api/v1/map: the map as JSON, or as CAD/GIS layers (DXF, GeoJSON).
#include "apriori/export/dxf_writer.h"
#include "apriori/export/geojson_writer.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/world/map_layers.h"

namespace wm::api {

Response get_map(const Call& call) {
  const auto snap = call.world.snapshot();
  const auto& options = call.world.world_options();
  const auto format = call.target.param("format").value_or("json");
  if (format == "json") return json_response(call.request, json_codec::map_json(*snap, options));
  if (format == "dxf")
    return raw_response(call.request, apriori::write_dxf(world::map_layers(*snap, options)), "image/vnd.dxf");
  if (format == "geojson")
    return raw_response(call.request, apriori::write_geojson(world::map_layers(*snap, options)),
                        "application/geo+json");
  throw bad_request("format", "expected json, dxf or geojson");
}

}  // namespace wm::api
