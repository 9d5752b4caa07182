// POST /api/v1/scans: a laser or sonar scan, or a batch of them, journaled with the decisions on their lines, then put
// in the grids. The body is JSON or CBOR: both decode to one document that one validation reads.
#include <boost/beast/http/field.hpp>

#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/request.h"
#include "server/api/response.h"
#include "server/json/answers.h"

namespace wm::api {

namespace {

json_codec::BodyFormat scan_body_format(const Request& request) {
  if (request.body().empty()) throw bad_request("", "empty body");
  if (has_content_type(request, "application/json")) return json_codec::BodyFormat::json;
  if (has_content_type(request, "application/cbor")) return json_codec::BodyFormat::cbor;
  throw ApiError(415, "unsupported_media_type",
                 "send the scan as Content-Type: application/json or application/cbor (got '" +
                     std::string(header(request, boost::beast::http::field::content_type)) + "')");
}

nlohmann::json scan_answer(const service::ScanOutcome& outcome) {
  nlohmann::json answer = {{"seq", outcome.seq}, {"grid_revision", outcome.grid_revision}, {"lines", nullptr}};
  if (const auto& lines = outcome.lines) {
    answer["lines"] = {{"observation", lines->seq},
                       {"version", lines->version},
                       {"decisions", json_codec::decisions_json(lines->decisions)}};
  }
  if (const auto& placement = outcome.placement) {
    // Where the lines and beams were placed: a robot may take the aligned pose back into its localisation.
    answer["pose"] = {{"x", placement->placed.x_m},
                      {"y", placement->placed.y_m},
                      {"theta", placement->placed.theta_rad},
                      {"dx", placement->placed.x_m - placement->posted.x_m},
                      {"dy", placement->placed.y_m - placement->posted.y_m},
                      {"dtheta", placement->placed.theta_rad - placement->posted.theta_rad},
                      {"aligned", placement->aligned()}};
  }
  return answer;
}

}  // namespace

Response post_scan(const Call& call) {
  require_token(call.request, call.options);
  const auto format = scan_body_format(call.request);
  auto body = json_codec::parse_scan_body(call.request.body(), format, call.options.scan_limits);
  if (!body.batch) {
    const auto outcome =
        call.world.ingest.post_scan(std::move(body.scans.front()), call.request.body(), request_id(call.request));
    auto response = json_response(call.request, scan_answer(outcome));
    if (outcome.replayed) response.set("Idempotent-Replayed", "true");
    return response;
  }
  const auto outcomes =
      call.world.ingest.post_scans(std::move(body.scans), call.request.body(), request_id(call.request));
  nlohmann::json answers = nlohmann::json::array();
  bool replayed = false;
  for (const auto& outcome : outcomes) {
    answers.push_back(scan_answer(outcome));
    replayed = replayed || outcome.replayed;
  }
  auto response = json_response(call.request, {{"scans", std::move(answers)}});
  if (replayed) response.set("Idempotent-Replayed", "true");
  return response;
}

}  // namespace wm::api
