// GET /api/v1/health.
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {
namespace {

nlohmann::json counts_json(const common::Diagnostics::Counts& counts) {
  return {{"info", counts.info}, {"warnings", counts.warnings}, {"errors", counts.errors}};
}

// What the server reported since it started: counts (in total and by where) and the last few reports, oldest first.
nlohmann::json diagnostics_json(const common::Diagnostics& diagnostics) {
  const auto summary = diagnostics.summary();
  auto json = counts_json(summary.total);
  auto& by_where = json["by_where"] = nlohmann::json::object();
  for (const auto& [where, counts] : summary.by_where) by_where[where] = counts_json(counts);
  auto& recent = json["recent"] = nlohmann::json::array();
  for (const auto& r : summary.recent)
    recent.push_back({{"at", r.at_unix_s},
                      {"where", r.where},
                      {"severity", std::string(common::severity_name(r.severity))},
                      {"message", r.message}});
  return json;
}

}  // namespace

Response get_health(const Call& call) {
  const auto snap = call.world.map.snapshot();
  nlohmann::json body{{"status", "ok"},
                      {"version", snap->version},
                      {"plan", snap->plan_name},
                      {"objects", snap->objects.size()},
                      {"elements", snap->elements.size()},
                      {"last_decision_seq", snap->last_decision_seq},
                      {"rules", json_codec::rules_status_json(call.world.rules.rules_status())}};
  if (call.diagnostics) body["diagnostics"] = diagnostics_json(*call.diagnostics);
  return json_response(call.request, body);
}

}  // namespace wm::api
