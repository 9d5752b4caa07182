// GET /api/v1/cluster: the nodes of this node's cluster, which maps each serves, and every map's lease and epoch.
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {

Response get_cluster(const Call& call) {
  if (!call.cluster)
    throw ApiError(404, "not_a_cluster", "this wmd is no cluster's node (wmd --store postgresql://… --cluster-id ID)");
  const auto status = call.cluster->status();
  nlohmann::json nodes = nlohmann::json::array();
  for (const auto& node : status.nodes)
    nodes.push_back({{"node", node.node},
                     {"url", node.url},
                     {"alive", node.alive},
                     {"self", node.node == status.node_id},
                     {"heartbeat_age_s", node.heartbeat_age_s},
                     {"up_s", node.up_s},
                     {"maps", node.maps}});
  nlohmann::json leases = nlohmann::json::array();
  for (const auto& lease : status.leases)
    leases.push_back({{"map", lease.map},
                      {"node", lease.node},
                      {"epoch", lease.epoch},
                      {"expires_in_s", lease.expires_in_s},
                      {"live", lease.expires_in_s > 0}});
  return json_response(call.request, {{"cluster", status.cluster_id},
                                      {"node", status.node_id},
                                      {"lease_ttl_s", call.cluster->options().lease_ttl.count() / 1000.0},
                                      {"nodes", std::move(nodes)},
                                      {"leases", std::move(leases)},
                                      {"unowned", status.unowned},
                                      {"taken_over", status.taken},
                                      {"lost", status.lost},
                                      {"handed_over", status.handed_over}});
}

}  // namespace wm::api
