// GET /api/v1/health.
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {

Response get_health(const Call& call) {
  const auto snap = call.world.snapshot();
  return json_response(call.request, {{"status", "ok"},
                                      {"version", snap->version},
                                      {"plan", snap->plan_name},
                                      {"objects", snap->objects.size()},
                                      {"elements", snap->elements.size()},
                                      {"last_decision_seq", snap->last_decision_seq},
                                      {"rules", json_codec::rules_status_json(call.world.rules_status())}});
}

}  // namespace wm::api
