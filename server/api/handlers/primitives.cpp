// POST /api/v1/primitives: line primitives decided by the rules and applied whole or not at all.
#include "server/api/access.h"
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/json/answers.h"

namespace wm::api {

Response post_primitives(const Call& call) {
  require_token(call.request, call.options);
  require_json_body(call.request);
  auto observation =
      json_codec::parse_primitives(call.request.body(), call.world.map.world_options(), call.options.primitive_limits);
  const auto outcome =
      call.world.ingest.post_primitives(std::move(observation), call.request.body(), request_id(call.request));
  auto response = json_response(call.request, {{"seq", outcome.seq},
                                               {"version", outcome.version},
                                               {"decisions", json_codec::decisions_json(outcome.decisions)}});
  // A retry's answer (the original one, nothing applied again) says so.
  if (outcome.replayed) response.set("Idempotent-Replayed", "true");
  return response;
}

}  // namespace wm::api
