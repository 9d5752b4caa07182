#pragma once

#include <string>

#include <boost/beast/http.hpp>

#include "apriori/floor_plan.h"
#include "apriori/import/layer_mapping.h"
#include "server/json/codec.h"
#include "server/service/world_service.h"

namespace wm::api {

using Request = boost::beast::http::request<boost::beast::http::string_body>;
using Response = boost::beast::http::response<boost::beast::http::string_body>;

struct ApiOptions {
  /// When non-empty, requests that change state need "Authorization: Bearer <token>".
  std::string token;
  json_codec::PrimitiveLimits primitive_limits;
  json_codec::ScanLimits scan_limits;
  apriori::FloorPlanLimits plan_limits;
  std::size_t max_decisions_per_page = 10000;
  /// Layer/block → kind and attributes for DXF uploads without their own mapping (--layer-mapping FILE).
  apriori::LayerMapping layer_mapping = apriori::default_layer_mapping();
  /// The web viewer's static files (index.html at "/", the rest under "/web/"); empty: not served.
  std::string web_dir;
};

/// What the handlers work on; built by main and passed down.
struct Services {
  ApiOptions options;
  service::WorldService& world;
};

/// Answers one HTTP request. A pure function of the request and the services: no sockets, never throws;
/// every failure becomes a JSON error {"error", "detail"} with its status (400, 401, 404, 405, 413, 415,
/// 422, 500, 503).
Response handle_request(const Request& request, Services& services);

/// The JSON error response used everywhere (also by the connection code for 413 and header errors).
Response error_response(unsigned http_version, bool keep_alive, int status, const std::string& error,
                        const std::string& detail);

}  // namespace wm::api
