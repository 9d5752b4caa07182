// POST /api/v1/scans: a laser or sonar scan, journaled with the decisions on its lines, then put in the grids.
#include "server/api/access.h"
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/json/answers.h"

namespace wm::api {

Response post_scan(const Call& call) {
  require_token(call.request, call.options);
  require_json_body(call.request);
  auto scan = json_codec::parse_scan(call.request.body(), call.options.scan_limits);
  const auto outcome = call.world.ingest.post_scan(std::move(scan), call.request.body(), request_id(call.request));
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
  auto response = json_response(call.request, answer);
  if (outcome.replayed) response.set("Idempotent-Replayed", "true");
  return response;
}

}  // namespace wm::api
