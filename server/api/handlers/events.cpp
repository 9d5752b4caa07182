// GET /api/v1/events without "Upgrade: websocket": the route is a WebSocket (the transport takes upgrades over
// before any handler), so a plain GET is told to upgrade (426, RFC 9110 section 15.5.22).
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {

Response get_events_without_upgrade(const Call& call) {
  auto response =
      error_response(call.request.version(), call.request.keep_alive(), 426, "upgrade_required",
                     "GET /api/v1/events is a WebSocket: send 'Connection: Upgrade' and 'Upgrade: websocket'");
  response.set(boost::beast::http::field::upgrade, "websocket");
  return response;
}

}  // namespace wm::api
