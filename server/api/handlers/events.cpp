// A plain GET (without "Upgrade: websocket") of a WebSocket route, /api/v1/events or /foxglove: the transport takes
// upgrades over before any handler, so this one is told to upgrade (426, RFC 9110 section 15.5.22).
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/api/routes.h"

namespace wm::api {

Response get_websocket_without_upgrade(const Call& call) {
  std::string detail =
      "GET " + call.target.path + " is a WebSocket: send 'Connection: Upgrade' and 'Upgrade: websocket'";
  if (const auto* route = websocket_route(call.target.path); route && !route->subprotocol.empty())
    detail += " and offer the subprotocol in 'Sec-WebSocket-Protocol: " + std::string(route->subprotocol) + "'";
  auto response = error_response(call.request.version(), call.request.keep_alive(), 426, "upgrade_required", detail);
  response.set(boost::beast::http::field::upgrade, "websocket");
  return response;
}

}  // namespace wm::api
