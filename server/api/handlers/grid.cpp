// The occupancy grids: a layer as JSON or PGM, the map_server pair, and the grid line extractor on request.
#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdlib>

#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/formats/map_server.h"
#include "server/json/answers.h"

namespace wm::api {
namespace {

using Layer = fusion::GridLayer;

// Largest answers [cells]: JSON costs ~7 bytes a cell, PGM one.
constexpr std::int64_t kMaxJsonCells = 4'000'000;
constexpr std::int64_t kMaxImageCells = 64'000'000;

nlohmann::json layer_names() {
  nlohmann::json names = nlohmann::json::array();
  for (const auto name : fusion::kGridLayerNames) names.push_back(std::string(name));
  return names;
}

Layer grid_layer(const std::string& name) {
  if (const auto layer = fusion::grid_layer_named(name)) return *layer;
  std::string expected;
  for (const auto known : fusion::kGridLayerNames) expected += (expected.empty() ? "" : ", ") + std::string(known);
  throw bad_request("layer", "expected one of " + expected);
}

// What the sonar side of the grids did (GET /api/v1/grid/tiles): seen, gated, the gate's verdicts.
nlohmann::json sonar_json(const service::GridSonarStatus& sonar) {
  return {{"seen", sonar.seen},
          {"gated_by_laser", sonar.gated},
          {"scans", sonar.counts.scans},
          {"readings",
           {{"kept", sonar.counts.kept},
            {"unjudged", sonar.counts.unjudged},
            {"phantom", sonar.counts.phantom},
            {"clipped", sonar.counts.clipped},
            {"ignored", sonar.counts.ignored}}}};
}

// The cells to export: the bbox given (x0,y0,x1,y1 in metres, snapped outwards to cells) or everything
// observed so far. @throw ApiError 404 when the grid is empty and no bbox was given.
fusion::GridGeometry grid_region(const Call& call, std::int64_t max_cells) {
  const auto bbox = query_bbox(call.target);
  if (!bbox) {
    const auto region = call.world.grid.grid_bounds();
    if (!region) throw ApiError(404, "empty_grid", "no scan has reached the grid yet; POST /api/v1/scans first");
    if (region->width() * region->height() > max_cells)
      throw bad_request("bbox", "the grid has more than " + std::to_string(max_cells) + " cells; give a bbox");
    return *region;
  }
  const double resolution = call.world.grid.grid_resolution_m();
  const auto cells = fusion::covering({bbox->x0, bbox->y0}, {bbox->x1, bbox->y1}, resolution);
  if (cells.width() * cells.height() > max_cells)
    throw bad_request("bbox", "more than " + std::to_string(max_cells) + " cells; ask for a smaller box");
  return cells.geometry(resolution);
}

Response pgm_response(const Call& call, Layer layer) {
  const auto region = grid_region(call, kMaxImageCells);
  const auto cells = call.world.grid.grid_layer(layer, region);
  return raw_response(call.request, formats::pgm_image(cells.values, region), "image/x-portable-graymap");
}

// The cells are written here rather than as a JSON array of a million values: nlohmann builds one node per cell
// and formats each double on its own, 1 s for the 1.4 M cells of the Intel lab.
void append_cells(std::string& body, const std::vector<float>& values) {
  body.reserve(body.size() + 16 + values.size() * 7);
  body += ",\"data\":[";
  char number[32];
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) body += ',';
    if (std::isnan(values[i])) {
      body += "null";
      continue;
    }
    const double rounded = std::round(static_cast<double>(values[i]) * 1e4) / 1e4;  // [0, 1] to 4 decimals
    const auto [end, ec] = std::to_chars(number, number + sizeof number, rounded);
    body.append(number, ec == std::errc() ? end : number);
  }
  body += "]}";
}

}  // namespace

Response get_grid(const Call& call) {
  const auto layer_name = call.target.param("layer").value_or("bayes");
  const auto layer = grid_layer(layer_name);
  const auto format = call.target.param("format").value_or("json");
  if (format != "json" && format != "pgm") throw bad_request("format", "expected json or pgm");
  if (format == "pgm") return pgm_response(call, layer);
  const auto region = grid_region(call, kMaxJsonCells);
  const auto cells = call.world.grid.grid_layer(layer, region);
  const nlohmann::json head = {{"layer", layer_name},
                               {"resolution", region.resolution_m()},
                               {"origin", nlohmann::json::array({region.origin_m().x(), region.origin_m().y()})},
                               {"width", region.width()},
                               {"height", region.height()},
                               {"revision", cells.revision},
                               {"order", "row-major from the lower-left cell; null = unknown"}};
  auto response = json_response(call.request, head);
  response.body().pop_back();  // the head's closing brace
  append_cells(response.body(), cells.values);
  response.prepare_payload();
  return response;
}

Response get_grid_tiles(const Call& call) {
  const auto tiles = call.world.grid.grid_tiles();
  nlohmann::json list = nlohmann::json::array();
  for (const auto& t : tiles.tiles) list.push_back({t.tx, t.ty, t.revision});
  return json_response(call.request,
                       {{"tile_size_cells", tiles.tile_size_cells},
                        {"resolution", tiles.resolution_m},
                        {"revision", tiles.revision},
                        {"layers", layer_names()},
                        {"sonar", sonar_json(call.world.grid.grid_sonar())},
                        {"tiles", std::move(list)},
                        {"order",
                         "[tx, ty, tile revision]; tile (tx, ty) holds cells [tx*T, (tx+1)*T) x [ty*T, "
                         "(ty+1)*T), cell (0, 0) at the world origin; GET /api/v1/grid/tiles/{layer}/{tx}/{ty}"},
                        {"server_instance", call.map_cache.instance()}});
}

// GET /api/v1/grid/tiles/{layer}/{tx}/{ty}: T² little-endian float32, row-major from the tile's lower-left cell, NaN
// for unknown; the ETag names the tile's revision in this server run.
Response get_grid_tile(const Call& call) {
  const auto& path = call.param;  // "layer/tx/ty": the route's three segments
  const auto first = path.find('/');
  const auto second = path.find('/', first + 1);
  const auto layer = grid_layer(path.substr(0, first));
  const auto index = [&](std::string_view text, const char* name) {
    std::int64_t value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc() || end != text.data() + text.size() || text.empty())
      throw bad_request(name, "expected an integer tile index, got '" + std::string(text) + "'");
    return value;
  };
  const std::string_view view(path);
  const auto tx = index(view.substr(first + 1, second - first - 1), "tx");
  const auto ty = index(view.substr(second + 1), "ty");
  const auto tile = call.world.grid.grid_tile(layer, tx, ty);
  if (!tile)
    throw ApiError(404, "no_tile",
                   "tile (" + std::to_string(tx) + ", " + std::to_string(ty) +
                       ") holds no observed cell; GET /api/v1/grid/tiles lists those that do");
  static_assert(std::endian::native == std::endian::little, "tiles are sent as little-endian float32");
  auto body = std::make_shared<MapBody>();
  body->version = static_cast<std::int64_t>(tile->revision);
  body->content_type = "application/octet-stream";
  body->bytes.assign(reinterpret_cast<const char*>(tile->values.data()), tile->values.size() * sizeof(float));
  return tagged_response(call.request, body, call.map_cache.instance() + "-r" + std::to_string(tile->revision),
                         /*may_gzip=*/false);
}

// The map_server pair: the YAML names map.pgm beside it; both describe the same region.
Response get_grid_map_yaml(const Call& call) {
  return raw_response(call.request, formats::map_yaml(grid_region(call, kMaxImageCells)), "application/yaml");
}

Response get_grid_map_pgm(const Call& call) { return pgm_response(call, Layer::bayes); }

Response post_grid_extract(const Call& call) {
  require_token(call.request, call.options);
  const auto outcome = call.world.ingest.extract_grid_lines();
  nlohmann::json answer = {{"segments", 0}, {"observation", nullptr}, {"decisions", nlohmann::json::array()}};
  if (outcome) {
    // One decision per segment (index >= 0); joins and end cuts the segments led to come with index -1.
    answer["segments"] = std::count_if(outcome->decisions.begin(), outcome->decisions.end(),
                                       [](const world::DecisionRecord& d) { return d.index >= 0; });
    answer["observation"] = outcome->seq;
    answer["decisions"] = json_codec::decisions_json(outcome->decisions);
  }
  return json_response(call.request, answer);
}

}  // namespace wm::api
