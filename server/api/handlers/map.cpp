// GET /api/v1/map: the map as JSON, or as CAD/GIS layers (DXF, GeoJSON); GET /api/v1/map/quality: how good it is.
#include <chrono>
#include <limits>
#include <memory>

#include "apriori/export/dxf_writer.h"
#include "apriori/export/geojson_writer.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/service/map_quality_report.h"
#include "server/world/map_layers.h"

namespace wm::api {

namespace {

// The map in `format` (json, dxf or geojson), whole or cut to `excerpt`. JSON names the server run its versions
// count in (`instance`): a delta from another run's version is not applicable.
std::string map_text(const world::WorldState& state, const world::WorldOptions& options, const std::string& format,
                     const std::optional<world::MapExcerpt>& excerpt, const std::string& instance) {
  if (format == "json") {
    auto map = json_codec::map_json(state, options, excerpt);
    map["server_instance"] = instance;
    return map.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  }
  if (format == "dxf") return apriori::write_dxf(world::map_layers(state, options, excerpt));
  return apriori::write_geojson(world::map_layers(state, options, excerpt), state.georeference);
}

std::string content_type_of(const std::string& format) {
  if (format == "json") return "application/json";
  if (format == "dxf") return "image/vnd.dxf";
  return "application/geo+json";
}

// GET /api/v1/map?since=V: what changed after version V. Elements and objects whose updated_version is newer come
// whole (upserts); ids that left the map are listed; the plan, placement and georeference always come.
// `shared_body` non-null: on an I/O thread (get_map_at_once), nullopt when the body is not made yet.
std::optional<Response> map_delta(const Call& call, const std::shared_ptr<const world::WorldState>& snap,
                                  std::int64_t since, std::shared_ptr<const std::string>* shared_body) {
  if (since > snap->version)
    throw ApiError(400, "bad_since",
                   "since=" + std::to_string(since) + " is after the map's version " + std::to_string(snap->version));
  const auto& options = call.world.map.world_options();
  auto& world = call.world.map;
  const auto body = call.map_cache.delta(
      snap, since,
      [&options, &world, since, instance = call.map_cache.instance()](const world::WorldState& state) {
        const auto removed = world.removed_since(since, state.version);
        if (!removed)
          throw ApiError(410, "since_too_old",
                         "this server no longer knows what was removed after version " + std::to_string(since) +
                             " (it keeps the newest 100 000 removed ids, from its start on): GET /api/v1/map in full");
        nlohmann::json objects = nlohmann::json::array(), elements = nlohmann::json::array();
        for (const auto& o : state.objects)
          if (o.updated_version > since) objects.push_back(json_codec::object_json(o, options));
        for (const auto& [number, e] : state.elements)
          if (e.updated_version > since) elements.push_back(json_codec::element_json(e));
        nlohmann::json delta{{"since", since},
                             {"version", state.version},
                             {"server_instance", instance},
                             {"plan", state.plan_name},
                             {"placement", json_codec::placement_json(state.placement, state.placement_cov)},
                             {"georeference", json_codec::georeference_json(state.georeference)},
                             {"objects", std::move(objects)},
                             {"elements", std::move(elements)},
                             {"removed", {{"elements", removed->elements}, {"objects", removed->objects}}}};
        return delta.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
      },
      shared_body != nullptr);
  if (!body) return std::nullopt;
  // A poller that holds the newest version asks the same question again and again: 304 until something changes.
  const auto tag = call.map_cache.instance() + "-v" + std::to_string(body->version) + "-since" + std::to_string(since);
  if (shared_body) return tagged_response_at_once(call.request, body, tag, *shared_body);
  return tagged_response(call.request, body, tag);
}

// GET /api/v1/map on a handler thread (`shared_body` nullptr: always an answer) or on an I/O thread (nullopt when
// it would have to wait or build).
std::optional<Response> map_answer(const Call& call, std::shared_ptr<const std::string>* shared_body) {
  const auto snap = call.world.map.snapshot();
  const auto& options = call.world.map.world_options();
  const auto format = call.target.param("format").value_or("json");
  if (format != "json" && format != "dxf" && format != "geojson")
    throw bad_request("format", "expected json, dxf or geojson");
  const auto bbox = query_bbox(call.target);
  if (call.target.param("since")) {
    if (format != "json") throw bad_request("since", "deltas come as JSON only (format=json)");
    if (bbox) throw bad_request("since", "a delta covers the whole map: leave out bbox");
    return map_delta(call, snap, query_int(call.target, "since", 0, 0, std::numeric_limits<std::int64_t>::max()),
                     shared_body);
  }
  if (bbox) {
    if (shared_body) return std::nullopt;
    // A window is cut for each request (its bytes depend on the box); the whole map is made once per version.
    const auto excerpt = world::map_excerpt(*snap, world::Box{bbox->x0, bbox->y0, bbox->x1, bbox->y1});
    if (format == "json") {
      auto body = json_codec::map_json(*snap, options, excerpt);
      body["bbox"] = {bbox->x0, bbox->y0, bbox->x1, bbox->y1};
      body["server_instance"] = call.map_cache.instance();
      return json_response(call.request, body);
    }
    return raw_response(call.request, map_text(*snap, options, format, excerpt, call.map_cache.instance()),
                        content_type_of(format));
  }
  // The builder may run in the background (max-stale): it refers to nothing of this request.
  auto& world = call.world.map;
  const auto body = call.map_cache.body(
      snap, format, content_type_of(format),
      [&options, format, instance = call.map_cache.instance(),
       &writer = call.map_cache.json_writer()](const world::WorldState& state) {
        if (format == "json") return writer.write(state, options, instance);
        return map_text(state, options, format, std::nullopt, instance);
      },
      accepted_staleness(call.request), [&world] { return world.snapshot(); }, shared_body != nullptr);
  if (!body) return std::nullopt;
  const auto tag = call.map_cache.instance() + "-v" + std::to_string(body->version);
  auto answer = shared_body ? tagged_response_at_once(call.request, body, tag, *shared_body)
                            : std::optional<Response>(tagged_response(call.request, body, tag));
  if (!answer) return std::nullopt;
  auto& response = *answer;
  if (body->version < snap->version) {
    // An older map than the newest, as the client allowed: how old, in whole seconds (RFC 9111 5.1).
    const auto age = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::steady_clock::now() - body->taken);
    response.set(boost::beast::http::field::age, std::to_string(age.count()));
  }
  return answer;
}

}  // namespace

Response get_map(const Call& call) { return *map_answer(call, nullptr); }

std::optional<Response> get_map_at_once(const Call& call, std::shared_ptr<const std::string>& shared_body) {
  return map_answer(call, &shared_body);
}

Response get_map_quality(const Call& call) {
  const service::MapQualityReportOptions options;
  const auto report = service::measure_map_quality(call.world.map, call.world.grid, options);
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
