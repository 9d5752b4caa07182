#pragma once

#include <optional>
#include <string>
#include <vector>

#include <boost/beast/http.hpp>

#include "apriori/floor_plan.h"
#include "apriori/import/layer_mapping.h"
#include "server/json/codec.h"
#include "server/service/world_service.h"

namespace wm::api {

using Request = boost::beast::http::request<boost::beast::http::string_body>;
using Response = boost::beast::http::response<boost::beast::http::string_body>;

struct ApiOptions {
  /// When non-empty, requests that change state, dry runs and the events WebSocket need
  /// "Authorization: Bearer <token>" (the scheme in any case, RFC 7235); the WebSocket also takes ?token=.
  std::string token;
  /// POST /api/v1/rules/dry-run loads rule text into the server: without a token it is refused (403)
  /// unless this is set (--allow-dry-run-without-token).
  bool allow_dry_run_without_token = false;
  /// Host names (without port, lower case) that requests may name in their Host header; IP literals are
  /// always accepted (a DNS-rebinding page always arrives with its own name). Empty: no check.
  std::vector<std::string> allowed_hosts;
  /// Origins ("http://host:port", lower case) allowed besides the server's own for the events WebSocket and
  /// for requests that are not GET/HEAD. A request without Origin (not a browser) passes.
  std::vector<std::string> allowed_origins;
  /// Largest /api/v1/query answer sent [bytes]; bigger answers are refused with 422 answer_too_large.
  std::size_t max_query_answer_bytes = std::size_t{8} << 20;
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

/// Where the connection code runs a request's handler. `immediate`: on the I/O thread (cheap, never
/// blocks: health, the index); `read`: the read threads of the handler pool, may take long (map, grid,
/// queries, dry runs); `write`: the pool's own threads for writes, which wait for the single writer
/// (ingest, floor plans, reloads).
enum class Lane { immediate, read, write };
Lane handler_lane(const Request& request);

/// Decides a WebSocket upgrade of GET /api/v1/events: the Host check, the Origin allow-list (same origin
/// by default) and, when a token is configured, "Authorization: Bearer <token>" or "?token=<token>"
/// (browsers cannot set headers on a WebSocket). nullopt: upgrade; otherwise the refusal to send (421, 403
/// or 401). Never throws.
std::optional<Response> authorize_events(const Request& request, const Services& services);

/// Answers one HTTP request. A pure function of the request and the services: no sockets, never throws;
/// every failure becomes a JSON error {"error", "detail"} with its status (400, 401, 403, 404, 405, 413,
/// 415, 421, 422, 500, 503). The Host check comes first, for every request.
Response handle_request(const Request& request, Services& services);

/// The JSON error response used everywhere (also by the connection code for 413 and header errors).
Response error_response(unsigned http_version, bool keep_alive, int status, const std::string& error,
                        const std::string& detail);

}  // namespace wm::api
