// The rule files: their status, a reload, and a dry run of a candidate file against the logged decisions.
#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {

Response get_rules(const Call& call) {
  return json_response(call.request, json_codec::rules_status_json(call.world.rules.rules_status()));
}

Response post_rules_reload(const Call& call) {
  require_token(call.request, call.options);
  return json_response(call.request, json_codec::rules_status_json(call.world.rules.reload_rules()));
}

Response post_rules_dry_run(const Call& call) {
  // A dry run loads rule text into this process: like any write it needs the token, and with none configured
  // only an explicit start-up flag allows it.
  if (call.options.token.empty() && !call.options.allow_dry_run_without_token)
    throw ApiError(403, "forbidden",
                   "dry runs load rule text into the server and need a token: start wmd with --token TOKEN and send "
                   "'Authorization: Bearer TOKEN' (or, where every local user is trusted, with "
                   "--allow-dry-run-without-token)");
  require_token(call.request, call.options);
  const auto doc = parse_json_object(call.request);
  require_known_keys(doc, {"file", "text", "last"});
  const rules::RuleText candidate{string_field(doc, "file", 255), string_field(doc, "text", 4u << 20)};
  const std::size_t last = count_field(doc, "last", 1000, 100000);
  const auto outcome = call.world.rules.dry_run(candidate, last);
  nlohmann::json changes = nlohmann::json::array();
  for (const auto& c : outcome.changes)
    changes.push_back(
        {{"recorded", json_codec::decision_json(c.recorded)}, {"candidate", json_codec::decision_json(c.candidate)}});
  return json_response(call.request, {{"file", candidate.name},
                                      {"redecided", outcome.redecided},
                                      {"changed", outcome.changes.size()},
                                      {"changes", changes}});
}

}  // namespace wm::api
