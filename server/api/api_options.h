#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "apriori/floor_plan.h"
#include "apriori/import/layer_mapping.h"
#include "server/json/codec.h"

namespace wm::api {

/// What the handlers are configured with (wmd's flags, read once by server/config/).
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

}  // namespace wm::api
