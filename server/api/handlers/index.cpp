// GET /api/v1: the route table as JSON, so the index cannot disagree with what the server answers.
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/api/routes.h"

namespace wm::api {

Response get_index(const Call& call) {
  nlohmann::json endpoints = nlohmann::json::array();
  for (const auto& route : routes()) {
    auto name = route_name(route) + std::string(route.query);
    if (route.websocket) name += " (WebSocket)";
    endpoints.push_back(std::move(name));
  }
  return json_response(call.request, {{"service", "worldmodel"}, {"api", "/api/v1"}, {"endpoints", endpoints}});
}

}  // namespace wm::api
