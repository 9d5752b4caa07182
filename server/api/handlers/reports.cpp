// GET /api/v1/report/as-built: where the building differs from its drawing; GET /api/v1/changes: those differences
// as changes a person may accept into the plan.
#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/request.h"
#include "server/api/response.h"
#include "server/json/answers.h"
#include "server/json/codec.h"
#include "server/world/as_built.h"
#include "server/world/changes.h"

namespace wm::api {

Response get_as_built_report(const Call& call) {
  const auto snap = call.world.map.snapshot();
  const auto evidence = call.world.map.plan_report();
  return json_response(call.request,
                       json_codec::as_built_json(*snap, world::as_built_report(*snap, evidence.get()), evidence.get()));
}

namespace {

/// Who decides: "observer" (or the older "source") of an optional JSON body ({"observer": "alice"}), else "client".
std::string decider(const Call& call) {
  if (call.request.body().empty()) return "client";
  const auto doc = parse_json_object(call.request);
  require_known_keys(doc, {"observer", "source"});
  return json_codec::observer_of(doc).value_or("client");
}

/// A change id as listed: "c" and 12 hex digits. Anything else cannot be listed: 404 without asking the writer.
void require_change_id(const std::string& id) {
  const bool well_formed =
      id.size() == 13 && id[0] == 'c' && id.find_first_not_of("0123456789abcdef", 1) == std::string::npos;
  if (!well_formed) throw ApiError(404, "not_found", "no change '" + id.substr(0, 64) + "': ids are c + 12 hex digits");
}

nlohmann::json outcome_json(const service::ChangeOutcome& outcome) {
  nlohmann::json answer = {{"version", outcome.version},
                           {"change", outcome.change_id},
                           {"decision", json_codec::decision_json(outcome.decision)}};
  if (outcome.added_object) answer["object"] = *outcome.added_object;
  return answer;
}

}  // namespace

Response get_changes(const Call& call) {
  std::shared_ptr<const world::WorldState> snap;
  std::shared_ptr<const world::PlanReport> evidence;
  const auto changes = call.world.map.changes(snap, evidence);
  return json_response(call.request, json_codec::changes_json(*snap, *evidence, changes));
}

Response post_change_accept(const Call& call) {
  require_token(call.request, call.options);
  require_change_id(call.param);
  return json_response(call.request, outcome_json(call.world.plan.decide_change(call.param, true, decider(call))));
}

Response post_change_reject(const Call& call) {
  require_token(call.request, call.options);
  require_change_id(call.param);
  return json_response(call.request, outcome_json(call.world.plan.decide_change(call.param, false, decider(call))));
}

Response post_changes_undo(const Call& call) {
  require_token(call.request, call.options);
  return json_response(call.request, outcome_json(call.world.plan.undo_change(decider(call))));
}

}  // namespace wm::api
