// GET /api/v1/report/as-built: where the building differs from its drawing.
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/json/answers.h"
#include "server/world/as_built.h"

namespace wm::api {

Response get_as_built_report(const Call& call) {
  const auto snap = call.world.snapshot();
  return json_response(call.request, json_codec::as_built_json(*snap, world::as_built_report(*snap)));
}

}  // namespace wm::api
