#pragma once

// What the bridge's source files share, and nothing else includes: the Core (bridge.cpp runs its thread and
// serves its clients' calls; bridge_grid.cpp and bridge_topics.cpp make its messages) and the client it serves
// (bridge_client.cpp).
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "server/foxglove/bridge.h"
#include "server/foxglove/schemas.h"

namespace wm::foxglove::internal {

using Clock = std::chrono::steady_clock;
using Payload = std::shared_ptr<const std::string>;
using Layer = fusion::GridLayer;

inline std::uint64_t unix_ns_now() {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());
}
inline Payload share(std::string text) { return std::make_shared<const std::string>(std::move(text)); }

inline std::vector<Channel> fixed_channels() {
  return {{kGridChannel, "/grid", "foxglove.Grid", schemas::grid()},
          {kGridDsChannel, "/grid/ds", "foxglove.Grid", schemas::grid()},
          {kElementsChannel, "/map/elements", "foxglove.SceneUpdate", schemas::scene_update()},
          {kPlanChannel, "/map/plan", "foxglove.SceneUpdate", schemas::scene_update()},
          {kTfChannel, "/tf", "foxglove.FrameTransforms", schemas::frame_transforms()},
          {kDecisionsChannel, "/decisions", "foxglove.Log", schemas::log()}};
}

// How messages of a channel queue up for a client that has not read them yet. `latest`: each message is the whole
// state (the grid, a pose, every transform), so a newer one replaces one still queued for the same subscription;
// they are at most one per subscription and share their bytes with the bridge, so they do not count against the
// bound. `every`: changes (scene updates, decisions), each needed; they count against the bound.
enum class Delivery { latest, every };
inline Delivery delivery_of(std::uint32_t channel) {
  return channel == kElementsChannel || channel == kPlanChannel || channel == kDecisionsChannel ? Delivery::every
                                                                                                : Delivery::latest;
}

class FoxgloveClient;

// A request for the current state of one channel, for one subscription (a new one, or one of a client that fell
// behind).
struct InitialRequest {
  std::weak_ptr<FoxgloveClient> client;
  std::uint32_t subscription = 0;
  std::uint32_t channel = 0;
};

// One Foxglove client: its subscriptions and its bounded queue. The transport calls open, receive, take and close on
// the connection's strand; the bridge's thread pushes messages from its own.
class FoxgloveClient final : public http::WebSocketEndpoint, public std::enable_shared_from_this<FoxgloveClient> {
 public:
  explicit FoxgloveClient(std::shared_ptr<Bridge::Core> core) : core_(std::move(core)) {}

  std::string_view subprotocol() const override { return kSubprotocol; }
  void open(std::function<void()> wake) override;
  void receive(std::string_view message, bool binary) override;
  std::vector<http::WebSocketFrame> take() override;
  void close() override;

  // --- the bridge ---

  /// Queues a message of `channel` for each active subscription to it; the number of frames queued.
  std::size_t push_data(std::uint32_t channel, const Payload& payload, std::uint64_t stamp_ns);

  /// The current state for one subscription, then its activation: from now on it gets every message of its
  /// channel. Nothing when it was unsubscribed (or resubscribed to another channel) meanwhile. The current state
  /// does not count against the bound: it is what a client that fell behind is brought back with.
  std::size_t push_initial(std::uint32_t subscription, std::uint32_t channel, const std::vector<Payload>& payloads,
                           std::uint64_t stamp_ns);

  /// A text message (serverInfo, advertise, status). Statuses answering a client that sends without reading are
  /// dropped past kMaxQueuedTextBytes (serverInfo and advertise come first and are far below it).
  void push_text(std::string text);

  /// The last message: `text` (a status), after what is queued, then the transport closes the connection. Nothing
  /// is queued after it (the map the client followed was deleted).
  void push_last(std::string text);

  /// Whether it has an active subscription to the channel and keeps up: one that fell behind gets the current state
  /// when it reads again, so nothing needs to be made for it meanwhile.
  bool subscribed(std::uint32_t channel) const;

 private:
  struct Sub {
    std::uint32_t channel = 0;
    bool active = false;  // false until its current state is queued: changes before that would come out of order
  };

  struct Queued {
    http::WebSocketFrame frame;
    std::uint32_t subscription = 0;  // of a data frame
    bool counted = false;            // a change (Delivery::every) that counts against the bound
  };

  // Under mutex_. A client whose changes queued pass the bound loses every queued data frame (text stays) and
  // everything after, until it reads again; one change is always accepted when none is queued, so a change larger
  // than the bound still reaches a client that keeps up.
  bool push_data_locked(std::uint32_t subscription, const Payload& payload, std::uint64_t stamp_ns, Delivery delivery,
                        bool initial);
  void fall_behind();

  const std::shared_ptr<Bridge::Core> core_;
  mutable std::mutex mutex_;
  std::function<void()> wake_;
  std::deque<Queued> queue_;
  std::size_t counted_bytes_ = 0;  // of the changes queued [bytes]
  std::size_t counted_messages_ = 0;
  std::size_t text_bytes_ = 0;      // of the text messages queued
  std::uint64_t dropped_text_ = 0;  // statuses not queued for a client that did not read
  bool behind_ = false;
  std::uint64_t dropped_ = 0;  // since it last caught up
  bool closed_ = false;
  bool ending_ = false;                         // push_last was called: nothing more is queued
  std::map<std::uint32_t, Sub> subscriptions_;  // by the client's subscription id
};

}  // namespace wm::foxglove::internal

namespace wm::foxglove {

struct Bridge::Core {
  // The shared types by their short names, as the members and their definitions use them.
  using Clock = internal::Clock;
  using Payload = internal::Payload;
  using Layer = internal::Layer;
  using FoxgloveClient = internal::FoxgloveClient;
  using InitialRequest = internal::InitialRequest;

  Core(const FoxgloveOptions& o, service::WorldPorts w, events::EventHub& h, common::Diagnostics& d, ServerInfo i)
      : options(o), world(w), hub(h), diagnostics(d), info(std::move(i)), channels(internal::fixed_channels()) {}

  const FoxgloveOptions options;
  service::WorldPorts world;  // the map, grid and robots ports are what it reads
  events::EventHub& hub;
  common::Diagnostics& diagnostics;  // reported to from the bridge's thread only
  const ServerInfo info;

  std::atomic<std::uint64_t> messages{0}, superseded{0}, dropped{0}, resyncs{0}, grid_messages{0};
  std::atomic<std::size_t> last_grid_bytes{0};

  // The clients and the channels. Lock order: clients_mutex, then a client's own mutex; never the other way.
  mutable std::mutex clients_mutex;
  std::vector<std::weak_ptr<FoxgloveClient>> clients;
  std::vector<Channel> channels;

  // What wakes the bridge's thread. A leaf: nothing else is locked while it is held, so the event hub's wake (on the
  // writer's thread) waits for nobody.
  std::mutex wake_mutex;
  std::condition_variable wake_cv;
  bool events_pending = false;
  bool clients_changed = false;
  bool stopping = false;
  std::vector<InitialRequest> inbox;

  std::thread thread;

  // --- called by the clients (any thread) ---
  /// Registers the client and queues serverInfo and advertise for it, under one lock with every later advertise,
  /// so that it is told of every channel exactly once, after serverInfo.
  /// False, and nothing registered, when max_clients are served already.
  bool add_client(const std::shared_ptr<FoxgloveClient>& client);
  void remove_client(const FoxgloveClient* client);
  bool has_channel(std::uint32_t id) const;
  void request_initial(std::vector<InitialRequest> requests);
  void stop();
  void run();

 private:
  // --- the bridge's thread only ---
  // A copy of the grid's tiles for one channel's layers, refreshed tile by tile: a tile is read again only when its
  // revision moved, and each read holds the grid's lock for that one tile, so an insert never waits for more than
  // one tile's copy (as for the shared-memory export).
  struct TileCache {
    explicit TileCache(std::vector<Layer> l) : layers(std::move(l)) {}
    std::vector<Layer> layers;
    std::int64_t tile_size = 0;
    double resolution_m = 0;
    std::map<std::pair<std::int64_t, std::int64_t>, std::pair<std::uint64_t, std::vector<float>>> tiles;
    std::int64_t revision = -1;  // scans in the grid when its tiles were last listed
  };
  struct GridCache {
    std::int64_t revision = -1;
    Payload payload;  // null: none made
  };
  struct SentPose {
    double x = 0, y = 0, theta = 0, received_at = 0;
  };

  std::vector<std::shared_ptr<FoxgloveClient>> live_clients();
  bool has_subscribers(std::uint32_t channel);
  void publish(std::uint32_t channel, const Payload& payload, std::uint64_t stamp_ns);
  void follow_clients();
  void take_events();
  void produce();
  Clock::time_point next_wake() const;

  void refresh(TileCache& cache);
  std::optional<GridCache> build_grid(std::uint32_t channel);
  void produce_grids();
  void produce_scene(std::uint32_t channel);
  Payload full_scene(std::uint32_t channel);
  void produce_robots();
  std::uint32_t robot_channel(const std::string& id);
  void produce_decisions();
  void serve(const InitialRequest& request);

  std::shared_ptr<events::EventHub::Subscriber> subscriber_;
  std::uint64_t pass_ = 0;                                 // passes of run()'s loop
  std::uint64_t grid_built_pass_ = 0, ds_built_pass_ = 0;  // when a new subscription last had the grid built
  bool grid_dirty_ = false, elements_dirty_ = false, plan_dirty_ = false, robots_dirty_ = false,
       decisions_dirty_ = false;
  Clock::time_point next_grid_{}, next_update_{};
  // The last grid message of each channel made (what a new subscriber gets), and the revision every active subscriber
  // has been sent; they differ when a new subscriber's grid was read afresh.
  GridCache grid_cache_, ds_cache_;
  std::int64_t grid_published_ = -1, ds_published_ = -1;
  TileCache bayes_tiles_{{Layer::bayes}};
  TileCache ds_tiles_{{Layer::ds_belief, Layer::ds_plausibility, Layer::ds_conflict}};
  // The snapshot the last scene update of each topic was made from: the next one carries what changed since.
  std::shared_ptr<const world::WorldState> elements_sent_, plan_sent_;
  std::pair<std::int64_t, Payload> elements_full_{-1, nullptr}, plan_full_{-1, nullptr};  // by snapshot version
  std::map<std::string, std::uint32_t> robot_channels_;
  std::map<std::string, SentPose> robots_sent_;
  std::int64_t decision_cursor_ = 0;  // the last decision sent (or skipped while nobody subscribed)
};

}  // namespace wm::foxglove
