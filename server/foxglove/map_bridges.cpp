#include "server/foxglove/map_bridges.h"

#include <utility>

namespace wm::foxglove {

// One map's bridge and the map it reads: the bridge goes first (its thread stops), then the map is let go.
struct MapBridges::MapBridge {
  MapBridge(const FoxgloveOptions& options, std::shared_ptr<service::MapInstance> instance,
            common::Diagnostics& diagnostics, ServerInfo info)
      : map(std::move(instance)),
        bridge(options, service::WorldPorts(map->world), map->events, diagnostics, std::move(info)) {}

  std::shared_ptr<service::MapInstance> map;
  Bridge bridge;
};

namespace {

// A client of a map's bridge that holds the bridge (and so the map) while the transport holds it.
class MapClient final : public http::WebSocketEndpoint {
 public:
  MapClient(std::shared_ptr<MapBridges::MapBridge> owner, std::shared_ptr<http::WebSocketEndpoint> client)
      : owner_(std::move(owner)), client_(std::move(client)) {}

  std::string_view subprotocol() const override { return client_->subprotocol(); }
  void open(std::function<void()> wake) override { client_->open(std::move(wake)); }
  void receive(std::string_view message, bool binary) override { client_->receive(message, binary); }
  std::vector<http::WebSocketFrame> take() override { return client_->take(); }
  void close() override { client_->close(); }

 private:
  std::shared_ptr<MapBridges::MapBridge> owner_;  // declared first: let go after the client
  std::shared_ptr<http::WebSocketEndpoint> client_;
};

// A client of a map deleted after its upgrade was allowed: told so, then closed.
class GoneClient final : public http::WebSocketEndpoint {
 public:
  explicit GoneClient(const std::string& id) : text_(map_deleted_status(id)) {}

  std::string_view subprotocol() const override { return kSubprotocol; }
  void open(std::function<void()> wake) override { wake(); }
  void receive(std::string_view, bool) override {}
  std::vector<http::WebSocketFrame> take() override {
    if (told_) return {};
    told_ = true;
    http::WebSocketFrame last{false, text_, nullptr};
    last.close_after = true;
    return {std::move(last)};
  }
  void close() override {}

 private:
  std::string text_;
  bool told_ = false;
};

}  // namespace

MapBridges::MapBridges(const FoxgloveOptions& options, service::MapRegistry& maps, common::Diagnostics& diagnostics,
                       ServerInfo info, SessionOf session_of)
    : options_(options),
      maps_(maps),
      diagnostics_(diagnostics),
      info_(std::move(info)),
      session_of_(std::move(session_of)) {}

MapBridges::~MapBridges() = default;

std::shared_ptr<http::WebSocketEndpoint> MapBridges::connect(const std::string& id) {
  auto map = maps_.find(id);
  if (!map) return std::make_shared<GoneClient>(id);
  std::shared_ptr<MapBridge> bridge;
  {
    std::lock_guard lock(mutex_);
    bridge = bridges_[id].lock();
    // A map deleted and made again under the same id is another map: it gets a bridge of its own.
    if (!bridge || bridge->map != map) {
      ServerInfo info = info_;
      info.session_id = session_of_(map);
      info.metadata["map"] = id;
      info.metadata["api"] = "/api/v1/maps/" + id;
      bridge = std::make_shared<MapBridge>(options_, map, diagnostics_, std::move(info));
      bridges_[id] = bridge;
    }
    for (auto it = bridges_.begin(); it != bridges_.end();) it = it->second.expired() ? bridges_.erase(it) : ++it;
  }
  return std::make_shared<MapClient>(bridge, bridge->bridge.connect());
}

}  // namespace wm::foxglove
