#pragma once

// The Foxglove bridges of a server's maps other than the default: a client of /foxglove?map=ID gets that map's
// channels, from a bridge made when the map's first client comes and gone with its last.
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "common/diagnostics.h"
#include "server/foxglove/bridge.h"
#include "server/foxglove/foxglove_options.h"
#include "server/http/websocket_endpoint.h"
#include "server/service/map_registry.h"

namespace wm::foxglove {

class MapBridges {
 public:
  /// A map's session id (serverInfo's sessionId: the map's server_instance, so that a client tells a map deleted and
  /// made again from the same map).
  using SessionOf = std::function<std::string(const std::shared_ptr<service::MapInstance>&)>;

  /// `maps` and `diagnostics` must outlive this and every connection it made. `info` is the server's; each map's
  /// bridge adds "map" to its metadata and takes the map's session id.
  MapBridges(const FoxgloveOptions& options, service::MapRegistry& maps, common::Diagnostics& diagnostics,
             ServerInfo info, SessionOf session_of);
  ~MapBridges();
  MapBridges(const MapBridges&) = delete;
  MapBridges& operator=(const MapBridges&) = delete;

  /// A client of the map `id`'s bridge. The client keeps the map and its bridge alive; when the map is deleted, each
  /// of its clients gets an error status and is closed (at once when there is no such map: deleted since its upgrade
  /// was allowed).
  std::shared_ptr<http::WebSocketEndpoint> connect(const std::string& id);

  struct MapBridge;

 private:
  const FoxgloveOptions options_;
  service::MapRegistry& maps_;
  common::Diagnostics& diagnostics_;
  const ServerInfo info_;
  const SessionOf session_of_;
  mutable std::mutex mutex_;
  std::map<std::string, std::weak_ptr<MapBridge>> bridges_;
};

}  // namespace wm::foxglove
