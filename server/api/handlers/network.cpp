// GET /api/v1/network: the processing network the writes run on; PUT .../subtasks/{name} starts or stops a subtask,
// PUT .../components/{name}/params changes a component's parameters while it runs.
#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/request.h"
#include "server/api/response.h"

namespace wm::api {
namespace {

nlohmann::json network_json(const pipeline::NetworkStats& stats) {
  nlohmann::json ports = nlohmann::json::array(), functions = nlohmann::json::array(),
                 executors = nlohmann::json::array();
  for (const auto& p : stats.ports)
    ports.push_back({{"component", p.component},
                     {"port", p.port},
                     {"type", p.type},
                     {"policy", p.policy == pipeline::PortPolicy::fifo ? "fifo" : "latest"},
                     {"capacity", p.capacity},
                     {"depth", p.depth},
                     {"max_depth", p.max_depth},
                     {"pushed", p.pushed},
                     {"dropped", p.dropped},
                     {"refused", p.refused},
                     {"dropped_stopped", p.dropped_stopped}});
  for (const auto& f : stats.functions)
    functions.push_back({{"component", f.component},
                         {"function", f.function},
                         {"ports", f.ports},
                         {"peeks", f.peeks},
                         {"priority", f.priority},
                         {"activations", f.activations},
                         {"failures", f.failures},
                         {"busy_s", f.busy_s},
                         {"max_s", f.max_s},
                         {"mean_ms", f.activations ? 1e3 * f.busy_s / static_cast<double>(f.activations) : 0.0}});
  for (const auto& e : stats.executors)
    executors.push_back({{"name", e.name},
                         {"components", e.components},
                         {"cycles", e.cycles},
                         {"busy_s", e.busy_s},
                         {"wall_s", e.wall_s},
                         {"load", e.wall_s > 0 ? e.busy_s / e.wall_s : 0.0}});
  nlohmann::json components = nlohmann::json::array(), subtasks = nlohmann::json::array();
  for (const auto& c : stats.components)
    components.push_back({{"name", c.name},
                          {"kind", c.kind},
                          {"params", c.params},
                          {"settable", c.settable},
                          {"subtask", c.subtask ? nlohmann::json(*c.subtask) : nlohmann::json(nullptr)},
                          {"running", c.running}});
  for (const auto& t : stats.subtasks)
    subtasks.push_back({{"name", t.name}, {"running", t.running}, {"components", t.components}});
  return {{"task_file", stats.source},   {"source", stats.source},  // the name before "task_file", kept for clients
          {"executors", executors},      {"functions", functions}, {"ports", ports},
          {"components", components},    {"subtasks", subtasks},   {"connections", stats.connections},
          {"discarded", stats.discarded}};
}

// A parameter's value as a task file would give it: a number, a string or a boolean (checked by the component, as at
// start).
std::string param_text(const std::string& key, const nlohmann::json& value) {
  if (value.is_string()) return value.get<std::string>();
  if (value.is_boolean()) return value.get<bool>() ? "true" : "false";
  if (value.is_number_integer()) return std::to_string(value.get<std::int64_t>());
  if (value.is_number_unsigned()) return std::to_string(value.get<std::uint64_t>());
  if (value.is_number_float()) return value.dump();
  throw bad_request(key, std::string("expected a number, a string or a boolean, not ") + value.type_name());
}

}  // namespace

Response get_network(const Call& call) {
  return json_response(call.request, network_json(call.world.ingest.network_stats()));
}

Response put_network_subtask(const Call& call) {
  require_token(call.request, call.options);
  const auto body = parse_json_object(call.request);
  require_known_keys(body, {"running"});
  const auto running = body.find("running");
  if (running == body.end()) throw bad_request("running", "missing field");
  if (!running->is_boolean()) throw bad_request("running", "expected true or false");
  return json_response(call.request, network_json(call.world.ingest.set_network_subtask(call.param, *running)));
}

Response put_network_params(const Call& call) {
  require_token(call.request, call.options);
  const auto body = parse_json_object(call.request);
  std::map<std::string, std::string> changes;
  for (const auto& [key, value] : body.items()) changes[key] = param_text(key, value);
  return json_response(call.request, network_json(call.world.ingest.set_network_params(call.param, changes)));
}

}  // namespace wm::api
