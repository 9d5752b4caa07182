#pragma once

// The live side of the Foxglove WebSocket: one thread that turns the world model's changes into Foxglove messages
// once, and hands them to every client subscribed to their channel, each through a bounded queue of its own.
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "common/diagnostics.h"
#include "server/events/event_hub.h"
#include "server/foxglove/foxglove_options.h"
#include "server/foxglove/protocol.h"
#include "server/http/websocket_endpoint.h"
#include "server/service/world_port.h"

namespace wm::foxglove {

/// Fixed channel ids; each robot gets a PoseInFrame channel of its own, from kFirstRobotChannel on, advertised when it
/// is first heard of.
inline constexpr std::uint32_t kGridChannel = 1;        // /grid: foxglove.Grid, "probability" (Bayes, NaN unknown)
inline constexpr std::uint32_t kGridDsChannel = 2;      // /grid/ds: foxglove.Grid, "belief", "plausibility", "conflict"
inline constexpr std::uint32_t kElementsChannel = 3;    // /map/elements: foxglove.SceneUpdate, an entity per element
inline constexpr std::uint32_t kPlanChannel = 4;        // /map/plan: foxglove.SceneUpdate, an entity per CAD object
inline constexpr std::uint32_t kTfChannel = 5;          // /tf: foxglove.FrameTransforms, map → "<robot>/base_link"
inline constexpr std::uint32_t kDecisionsChannel = 6;   // /decisions: foxglove.Log, a message per decision
inline constexpr std::uint32_t kFirstRobotChannel = 7;  // /robots/<id>/pose: foxglove.PoseInFrame

/// What the bridge has done so far (tests, and the figures in docs/foxglove.md).
struct BridgeStats {
  std::size_t clients = 0;          // connected now
  std::uint64_t messages = 0;       // message data frames queued for clients
  std::uint64_t superseded = 0;     // grid, pose and transform messages replaced by a newer one before being sent
  std::uint64_t dropped = 0;        // message data frames dropped because their client fell behind
  std::uint64_t resyncs = 0;        // clients brought back up to the current state after falling behind
  std::uint64_t grid_messages = 0;  // grid messages built (/grid and /grid/ds)
  std::size_t last_grid_bytes = 0;  // size of the last /grid message [bytes]
};

/// Serves the Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1) to any number of clients.
///
/// Nothing on the write path waits for it: it learns of changes from the event hub (whose publish never blocks) and
/// reads the world through the port's snapshot and grid reads on its own thread, at nice +10 like the read handlers.
/// Each message is encoded once and shared by every subscriber; each client has a bounded queue
/// for changes (scene updates, decisions: FoxgloveOptions::max_queued_bytes, max_queued_messages); a whole-state
/// message (the grid, a pose, the transforms) replaces one of its subscription still queued, so a slow client gets
/// the latest grid rather than every grid. A client that falls behind loses its queued messages and, once it reads
/// again, gets a status warning and the current state of everything it subscribed to. The
/// grid is sent at most every grid_period and only when its revision moved; the rest is batched per update_period.
/// A new subscription gets the current state at once: the grid, the whole scene (a deletion of everything, then
/// every entity), the poses and transforms, the last initial_decisions decisions; then changes as they happen
/// (scene updates carry only the entities that changed and deletions of those removed).
/// The last status a client of a deleted map gets (an error naming the map; `map` empty: the server's own).
std::string map_deleted_status(std::string_view map);
/// The status a client of a map that moved to another node of the cluster gets last.
std::string map_moved_status(std::string_view map);

class Bridge {
 public:
  /// `world` and `hub` must outlive the bridge and every connection it made; `diagnostics` (what the bridge's thread
  /// could not send) must outlive the bridge.
  Bridge(const FoxgloveOptions& options, service::WorldPorts world, events::EventHub& hub,
         common::Diagnostics& diagnostics, ServerInfo info);
  ~Bridge();
  Bridge(const Bridge&) = delete;
  Bridge& operator=(const Bridge&) = delete;

  /// A new client: what the transport runs one upgraded WebSocket with. Its first messages are serverInfo and
  /// advertise.
  std::shared_ptr<http::WebSocketEndpoint> connect();
  BridgeStats stats() const;

  struct Core;  // shared with the clients, which may outlive a call into them

 private:
  std::shared_ptr<Core> core_;
};

}  // namespace wm::foxglove
