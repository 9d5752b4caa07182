// GET /api/v1/network: the processing network the writes run on.
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {

Response get_network(const Call& call) {
  const auto stats = call.world.ingest.network_stats();
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
                     {"refused", p.refused}});
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
  return json_response(call.request, {{"task_file", stats.source},
                                      {"source", stats.source},  // the name before "task_file", kept for clients
                                      {"executors", executors},
                                      {"functions", functions},
                                      {"ports", ports},
                                      {"connections", stats.connections},
                                      {"discarded", stats.discarded}});
}

}  // namespace wm::api
