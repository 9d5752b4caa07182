#include "server/foxglove/bridge.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "server/foxglove/messages.h"
#include "server/foxglove/schemas.h"

namespace wm::foxglove {
namespace {

using Clock = std::chrono::steady_clock;
using Payload = std::shared_ptr<const std::string>;
using Layer = fusion::OccupancyGrid::Layer;

// Like the read handlers (server/http/http_server.cpp): encoding megabytes of grid yields the CPU to ingest.
constexpr int kBridgeNice = 10;
// Decisions read from the log per page, and pages per turn (the rest follows on the next turn).
constexpr std::size_t kDecisionPage = 1000;
constexpr int kDecisionPagesPerTurn = 10;

std::uint64_t unix_ns_now() {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());
}
// Whole seconds and the fraction apart: a double of Unix seconds holds the fraction to the nanosecond, its product with
// 1e9 (about 1.7e18) only to 256 ns.
std::uint64_t unix_ns(double unix_s) {
  if (!(unix_s > 0)) return 0;
  const double whole = std::floor(unix_s);
  return static_cast<std::uint64_t>(whole) * 1'000'000'000u +
         static_cast<std::uint64_t>(std::llround((unix_s - whole) * 1e9));
}
Payload share(std::string text) { return std::make_shared<const std::string>(std::move(text)); }

// Frames and topics of robots: the ROS multi-robot convention (a prefix per robot), so a robot named "map" cannot
// take the map frame's name.
std::string robot_frame(const std::string& id) { return id + "/base_link"; }

std::vector<Channel> fixed_channels() {
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
Delivery delivery_of(std::uint32_t channel) {
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

}  // namespace

struct Bridge::Core {
  Core(const FoxgloveOptions& o, service::WorldPort& w, events::EventHub& h, common::Diagnostics& d, ServerInfo i)
      : options(o), world(w), hub(h), diagnostics(d), info(std::move(i)), channels(fixed_channels()) {}

  const FoxgloveOptions options;
  service::WorldPort& world;
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
  TileCache bayes_tiles_{{Layer::bayes_probability}};
  TileCache ds_tiles_{{Layer::ds_belief, Layer::ds_plausibility, Layer::ds_conflict}};
  // The snapshot the last scene update of each topic was made from: the next one carries what changed since.
  std::shared_ptr<const world::WorldState> elements_sent_, plan_sent_;
  std::pair<std::int64_t, Payload> elements_full_{-1, nullptr}, plan_full_{-1, nullptr};  // by snapshot version
  std::map<std::string, std::uint32_t> robot_channels_;
  std::map<std::string, SentPose> robots_sent_;
  std::int64_t decision_cursor_ = 0;  // the last decision sent (or skipped while nobody subscribed)
};

namespace {

// One Foxglove client: its subscriptions and its bounded queue. The transport calls open, receive, take and close on
// the connection's strand; the bridge's thread pushes messages from its own.
class FoxgloveClient final : public http::WebSocketEndpoint, public std::enable_shared_from_this<FoxgloveClient> {
 public:
  explicit FoxgloveClient(std::shared_ptr<Bridge::Core> core) : core_(std::move(core)) {}

  std::string_view subprotocol() const override { return kSubprotocol; }

  void open(std::function<void()> wake) override {
    {
      std::lock_guard lock(mutex_);
      wake_ = std::move(wake);
    }
    if (core_->add_client(shared_from_this())) return;
    std::function<void()> wake_now;
    {
      std::lock_guard lock(mutex_);
      queue_.push_back({{false,
                         status_json(StatusLevel::error, "too many Foxglove clients: this server serves " +
                                                             std::to_string(core_->options.max_clients) +
                                                             " at once; try again later"),
                         nullptr, true},
                        0,
                        false});
      wake_now = wake_;
    }
    if (wake_now) wake_now();
  }

  void receive(std::string_view message, bool binary) override {
    std::vector<std::string> replies;
    std::vector<InitialRequest> requests;
    if (binary) {
      replies.push_back(status_json(StatusLevel::error,
                                    "this server takes no binary messages (no clientPublish or services capability)"));
    } else {
      try {
        const auto parsed = parse_client_message(message);
        // At most one status per client message, naming the first few refusals: a message of a megabyte must not
        // make megabytes of replies for a client that does not read.
        Refusals refused;
        if (const auto* subscribe = std::get_if<Subscribe>(&parsed)) {
          std::vector<bool> known;
          for (const auto& s : subscribe->subscriptions) known.push_back(core_->has_channel(s.channel_id));
          std::lock_guard lock(mutex_);
          for (std::size_t i = 0; i < subscribe->subscriptions.size(); ++i) {
            const auto& s = subscribe->subscriptions[i];
            const bool channel_taken = std::any_of(subscriptions_.begin(), subscriptions_.end(),
                                                   [&](const auto& e) { return e.second.channel == s.channel_id; });
            if (!known[i]) {
              refused.add("no channel " + std::to_string(s.channel_id));
            } else if (subscriptions_.count(s.id) != 0) {
              refused.add("subscription id " + std::to_string(s.id) + " is in use");
            } else if (channel_taken) {
              // The protocol allows one subscription per channel and client; it also bounds what a client holds.
              refused.add("channel " + std::to_string(s.channel_id) + " is subscribed already");
            } else {
              subscriptions_.emplace(s.id, Sub{s.channel_id, false});
              requests.push_back({weak_from_this(), s.id, s.channel_id});
            }
          }
          if (refused.count > 0) replies.push_back(status_json(StatusLevel::error, refused.text("subscribe")));
        } else if (const auto* unsubscribe = std::get_if<Unsubscribe>(&parsed)) {
          std::lock_guard lock(mutex_);
          for (const auto id : unsubscribe->subscription_ids)
            if (subscriptions_.erase(id) == 0) refused.add("no subscription " + std::to_string(id));
          if (refused.count > 0) replies.push_back(status_json(StatusLevel::warning, refused.text("unsubscribe")));
        } else {
          auto op = std::get<Unsupported>(parsed).op;
          if (op.size() > kMaxEchoedOp) op = op.substr(0, kMaxEchoedOp) + "...";
          replies.push_back(
              status_json(StatusLevel::error,
                          "'" + op + "' is not supported: this server has no optional capability (it only publishes)"));
        }
      } catch (const ProtocolError& e) {
        std::string what = e.what();
        if (what.size() > 2 * kMaxEchoedOp) what = what.substr(0, 2 * kMaxEchoedOp) + "...";
        replies.push_back(status_json(StatusLevel::error, "bad message: " + what));
      }
    }
    for (auto& reply : replies) push_text(std::move(reply));
    if (!requests.empty()) core_->request_initial(std::move(requests));
  }

  std::vector<http::WebSocketFrame> take() override {
    std::vector<InitialRequest> requests;
    std::vector<http::WebSocketFrame> frames;
    {
      std::lock_guard lock(mutex_);
      if (behind_) {
        // It reads again: tell it what it missed, then bring every subscription back to the current state.
        behind_ = false;
        queue_.push_back({{false,
                           status_json(StatusLevel::warning,
                                       "this client fell behind: " + std::to_string(dropped_) +
                                           " messages were dropped; the current state of each subscription follows"),
                           nullptr},
                          0,
                          false});
        dropped_ = 0;
        for (auto& [id, sub] : subscriptions_) {
          sub.active = false;
          requests.push_back({weak_from_this(), id, sub.channel});
        }
        ++core_->resyncs;
      }
      frames.reserve(queue_.size());
      for (auto& queued : queue_) frames.push_back(std::move(queued.frame));
      queue_.clear();
      counted_bytes_ = 0;
      counted_messages_ = 0;
      text_bytes_ = 0;
    }
    if (!requests.empty()) core_->request_initial(std::move(requests));
    return frames;
  }

  void close() override {
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
      queue_.clear();
      subscriptions_.clear();
      wake_ = nullptr;
    }
    core_->remove_client(this);
  }

  // --- the bridge ---

  /// Queues a message of `channel` for each active subscription to it; the number of frames queued.
  std::size_t push_data(std::uint32_t channel, const Payload& payload, std::uint64_t stamp_ns) {
    std::size_t queued = 0;
    std::function<void()> wake;
    {
      std::lock_guard lock(mutex_);
      for (const auto& [id, sub] : subscriptions_)
        if (sub.active && sub.channel == channel &&
            push_data_locked(id, payload, stamp_ns, delivery_of(channel), false))
          ++queued;
      if (queued > 0) wake = wake_;
    }
    if (wake) wake();
    return queued;
  }

  /// The current state for one subscription, then its activation: from now on it gets every message of its
  /// channel. Nothing when it was unsubscribed (or resubscribed to another channel) meanwhile. The current state
  /// does not count against the bound: it is what a client that fell behind is brought back with.
  std::size_t push_initial(std::uint32_t subscription, std::uint32_t channel, const std::vector<Payload>& payloads,
                           std::uint64_t stamp_ns) {
    std::size_t queued = 0;
    std::function<void()> wake;
    {
      std::lock_guard lock(mutex_);
      const auto it = subscriptions_.find(subscription);
      if (it == subscriptions_.end() || it->second.channel != channel || it->second.active) return 0;
      for (const auto& payload : payloads)
        if (push_data_locked(subscription, payload, stamp_ns, delivery_of(channel), true)) ++queued;
      it->second.active = true;
      if (queued > 0) wake = wake_;
    }
    if (wake) wake();
    return queued;
  }

  /// A text message (serverInfo, advertise, status). Statuses answering a client that sends without reading are
  /// dropped past kMaxQueuedTextBytes (serverInfo and advertise come first and are far below it).
  void push_text(std::string text) {
    std::function<void()> wake;
    {
      std::lock_guard lock(mutex_);
      if (closed_) return;
      if (text_bytes_ + text.size() > kMaxQueuedTextBytes) {
        ++dropped_text_;
        return;
      }
      text_bytes_ += text.size();
      queue_.push_back({{false, std::move(text), nullptr}, 0, false});
      wake = wake_;
    }
    if (wake) wake();
  }

  /// Whether it has an active subscription to the channel and keeps up: one that fell behind gets the current state
  /// when it reads again, so nothing needs to be made for it meanwhile.
  bool subscribed(std::uint32_t channel) const {
    std::lock_guard lock(mutex_);
    if (behind_ || closed_) return false;
    return std::any_of(subscriptions_.begin(), subscriptions_.end(),
                       [&](const auto& entry) { return entry.second.active && entry.second.channel == channel; });
  }

 private:
  static constexpr std::size_t kMaxEchoedOp = 64;                // characters of a client's text quoted back
  static constexpr std::size_t kMaxQueuedTextBytes = 256 << 10;  // statuses waiting for a client that does not read

  // Refusals within one client message, told in one status.
  struct Refusals {
    std::size_t count = 0;
    std::string first;
    void add(const std::string& what) {
      if (count++ < 3) first += (first.empty() ? "" : "; ") + what;
    }
    std::string text(const std::string& op) const {
      return op + ": " + first + (count > 3 ? "; and " + std::to_string(count - 3) + " more" : "");
    }
  };

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
                        bool initial) {
    if (closed_) return false;
    if (behind_) {
      ++dropped_;
      ++core_->dropped;
      return false;
    }
    if (delivery == Delivery::latest) {
      for (auto& queued : queue_)
        if (queued.frame.binary && queued.subscription == subscription) {
          queued.frame.head = message_data_header(subscription, stamp_ns);
          queued.frame.body = payload;
          ++core_->superseded;
          return true;
        }
    } else if (!initial) {
      const std::size_t bytes = kMessageDataHeaderBytes + payload->size();
      const auto& o = core_->options;
      if (counted_messages_ > 0 &&
          (counted_messages_ + 1 > o.max_queued_messages || counted_bytes_ + bytes > o.max_queued_bytes)) {
        fall_behind();
        return false;
      }
      counted_bytes_ += bytes;
      ++counted_messages_;
    }
    queue_.push_back({{true, message_data_header(subscription, stamp_ns), payload},
                      subscription,
                      delivery == Delivery::every && !initial});
    ++core_->messages;
    return true;
  }

  void fall_behind() {
    const auto lost = static_cast<std::uint64_t>(
        std::count_if(queue_.begin(), queue_.end(), [](const Queued& q) { return q.frame.binary; }));
    std::erase_if(queue_, [](const Queued& q) { return q.frame.binary; });
    counted_bytes_ = 0;
    counted_messages_ = 0;
    dropped_ += lost + 1;
    core_->dropped += lost + 1;
    behind_ = true;
  }

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
  std::map<std::uint32_t, Sub> subscriptions_;  // by the client's subscription id
};

}  // namespace

// --- Core: the clients' side ---

bool Bridge::Core::add_client(const std::shared_ptr<FoxgloveClient>& client) {
  {
    std::lock_guard lock(clients_mutex);
    std::erase_if(clients, [](const auto& c) { return c.expired(); });
    if (clients.size() >= options.max_clients) return false;
    clients.push_back(client);
    client->push_text(server_info_json(info));
    client->push_text(advertise_json(channels));
  }
  {
    std::lock_guard lock(wake_mutex);
    clients_changed = true;
  }
  wake_cv.notify_one();
  return true;
}

void Bridge::Core::remove_client(const FoxgloveClient* client) {
  {
    std::lock_guard lock(clients_mutex);
    std::erase_if(clients, [client](const auto& c) {
      const auto locked = c.lock();
      return !locked || locked.get() == client;
    });
  }
  {
    std::lock_guard lock(wake_mutex);
    clients_changed = true;
  }
  wake_cv.notify_one();
}

bool Bridge::Core::has_channel(std::uint32_t id) const {
  std::lock_guard lock(clients_mutex);
  return std::any_of(channels.begin(), channels.end(), [id](const Channel& c) { return c.id == id; });
}

void Bridge::Core::request_initial(std::vector<InitialRequest> requests) {
  {
    std::lock_guard lock(wake_mutex);
    for (auto& r : requests) inbox.push_back(std::move(r));
  }
  wake_cv.notify_one();
}

void Bridge::Core::stop() {
  {
    std::lock_guard lock(wake_mutex);
    stopping = true;
  }
  wake_cv.notify_all();
  if (thread.joinable()) thread.join();
  if (subscriber_) {
    hub.unsubscribe(subscriber_);
    subscriber_.reset();
  }
}

// --- Core: the bridge's thread ---

void Bridge::Core::run() {
  ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), kBridgeNice);  // best effort
  std::unique_lock lock(wake_mutex);
  for (;;) {
    const auto deadline = next_wake();
    wake_cv.wait_until(lock, deadline,
                       [this] { return stopping || events_pending || clients_changed || !inbox.empty(); });
    if (stopping) return;
    const bool events = std::exchange(events_pending, false);
    const bool changed = std::exchange(clients_changed, false);
    auto requests = std::exchange(inbox, {});
    lock.unlock();
    ++pass_;
    try {
      if (changed) follow_clients();
      if (events && subscriber_) take_events();
    } catch (const std::exception& e) {  // a malformed event: what it said is lost, the next one brings it
      diagnostics.report(common::Severity::warning, "foxglove", std::string("foxglove: ") + e.what());
    }
    produce();
    for (const auto& request : requests) {
      try {
        serve(request);
      } catch (const std::exception& e) {
        diagnostics.report(
            common::Severity::warning, "foxglove",
            "foxglove: current state of channel " + std::to_string(request.channel) + " not sent: " + e.what());
      }
    }
    lock.lock();
  }
}

std::vector<std::shared_ptr<FoxgloveClient>> Bridge::Core::live_clients() {
  std::vector<std::shared_ptr<FoxgloveClient>> live;
  std::lock_guard lock(clients_mutex);
  for (const auto& c : clients)
    if (auto locked = c.lock()) live.push_back(std::move(locked));
  return live;
}

bool Bridge::Core::has_subscribers(std::uint32_t channel) {
  const auto live = live_clients();
  return std::any_of(live.begin(), live.end(), [channel](const auto& c) { return c->subscribed(channel); });
}

void Bridge::Core::publish(std::uint32_t channel, const Payload& payload, std::uint64_t stamp_ns) {
  for (const auto& client : live_clients()) client->push_data(channel, payload, stamp_ns);
}

// The hub is listened to only while a client is connected: with none, the world service builds no events for us.
void Bridge::Core::follow_clients() {
  const bool any = !live_clients().empty();
  if (any && !subscriber_) {
    subscriber_ = hub.subscribe([this] {
      {
        std::lock_guard lock(wake_mutex);
        events_pending = true;
      }
      wake_cv.notify_one();
    });
    // Whatever happened while nobody listened: everything is stale.
    grid_dirty_ = elements_dirty_ = plan_dirty_ = robots_dirty_ = decisions_dirty_ = true;
    grid_cache_ = ds_cache_ = {};
    grid_published_ = ds_published_ = -1;
    elements_sent_.reset();
    plan_sent_.reset();
    decision_cursor_ = world.snapshot()->last_decision_seq;
  } else if (!any && subscriber_) {
    hub.unsubscribe(subscriber_);
    subscriber_.reset();
  }
}

void Bridge::Core::take_events() {
  for (const auto& text : subscriber_->take()) {
    // Events only say what changed; the messages are made from the world itself, so a parse error is no loss.
    const auto event = nlohmann::json::parse(text, nullptr, false);
    const std::string type = event.is_object() ? event.value("type", "") : "";
    if (type == "scan") {
      grid_dirty_ = robots_dirty_ = true;
    } else if (type == "robot") {
      robots_dirty_ = true;
    } else if (type == "rules") {
      // the rules changed, not the map
    } else {  // update, floorplan, placement, georeference; resync (the hub dropped events for us): everything
      elements_dirty_ = plan_dirty_ = decisions_dirty_ = true;
      if (type != "update" && type != "floorplan" && type != "placement" && type != "georeference")
        grid_dirty_ = robots_dirty_ = true;
    }
  }
}

Clock::time_point Bridge::Core::next_wake() const {
  auto wake = Clock::time_point::max();
  if (grid_dirty_) wake = std::min(wake, next_grid_);
  if (elements_dirty_ || plan_dirty_ || robots_dirty_ || decisions_dirty_) wake = std::min(wake, next_update_);
  return wake;
}

void Bridge::Core::produce() {
  const auto now = Clock::now();
  // A failure (a storage error reading decisions, a grid read refused) leaves its flag set: tried again next period.
  const auto attempt = [this](const char* what, auto&& step) {
    try {
      step();
    } catch (const std::exception& e) {
      diagnostics.report(common::Severity::warning, "foxglove",
                         std::string("foxglove: ") + what + " not sent: " + e.what());
    }
  };
  if (grid_dirty_ && now >= next_grid_) {
    next_grid_ = now + options.grid_period;
    attempt("grid", [this] { produce_grids(); });
  }
  if ((elements_dirty_ || plan_dirty_ || robots_dirty_ || decisions_dirty_) && now >= next_update_) {
    next_update_ = now + options.update_period;
    if (robots_dirty_) attempt("robot poses", [this] { produce_robots(); });
    if (elements_dirty_) attempt("elements", [this] { produce_scene(kElementsChannel); });
    if (plan_dirty_) attempt("plan", [this] { produce_scene(kPlanChannel); });
    if (decisions_dirty_) attempt("decisions", [this] { produce_decisions(); });
  }
}

// Lists the tiles and reads those whose revision moved (and those never read).
void Bridge::Core::refresh(TileCache& cache) {
  const auto listing = world.grid_tiles();
  if (listing.tile_size_cells != cache.tile_size || listing.resolution_m != cache.resolution_m) {
    cache.tiles.clear();
    cache.tile_size = listing.tile_size_cells;
    cache.resolution_m = listing.resolution_m;
  }
  const auto cells = static_cast<std::size_t>(cache.tile_size * cache.tile_size);
  for (const auto& t : listing.tiles) {
    auto& [revision, values] = cache.tiles[{t.tx, t.ty}];
    if (revision == t.revision && !values.empty()) continue;
    if (cache.layers.size() == 1) {
      auto tile = world.grid_tile(cache.layers.front(), t.tx, t.ty);
      if (!tile) continue;
      revision = tile->revision;
      values = std::move(tile->values);
    } else {  // every layer of the tile under one lock: all of one revision; the DS ones follow Bayes in Layer order
      auto tile = world.grid_tile_layers(t.tx, t.ty);
      if (!tile || tile->values.size() < 4 * cells) continue;
      revision = tile->revision;
      values.assign(tile->values.begin() + static_cast<std::ptrdiff_t>(cells), tile->values.end());
    }
  }
  cache.revision = listing.revision;
}

namespace {

std::int64_t floor_div(std::int64_t a, std::int64_t b) { return a / b - ((a % b != 0) && ((a < 0) != (b < 0))); }

// Rows [y0, y1) of `region` (whose cells are the grid's own) from a tile cache, one field per layer; cells of no
// tile are NaN.
template <typename Tiles>
std::vector<GridField> assemble(const Tiles& tiles, std::int64_t tile_size, std::size_t layer_count,
                                const std::vector<std::string>& names, const fusion::GridGeometry& region,
                                std::int64_t y0, std::int64_t y1) {
  const double r = region.resolution_m();
  const auto cx0 = static_cast<std::int64_t>(std::llround(region.origin_m().x() / r));
  const auto cy0 = static_cast<std::int64_t>(std::llround(region.origin_m().y() / r));
  const std::int64_t w = region.width(), t = tile_size;
  std::vector<GridField> fields;
  for (std::size_t l = 0; l < layer_count; ++l)
    fields.push_back({names[l], std::vector<float>(static_cast<std::size_t>(w * (y1 - y0)), std::nanf(""))});
  for (std::int64_t y = y0; y < y1; ++y) {
    const std::int64_t cy = cy0 + y, ty = floor_div(cy, t), iy = cy - ty * t;
    for (std::int64_t x = 0; x < w;) {
      const std::int64_t cx = cx0 + x, tx = floor_div(cx, t), ix = cx - tx * t;
      const std::int64_t run = std::min(t - ix, w - x);  // cells of this row in this tile
      if (const auto it = tiles.find({tx, ty}); it != tiles.end() && !it->second.second.empty()) {
        const auto& values = it->second.second;
        for (std::size_t l = 0; l < layer_count; ++l) {
          const auto from = values.begin() + static_cast<std::ptrdiff_t>(l * t * t + iy * t + ix);
          std::copy(from, from + run, fields[l].values.begin() + static_cast<std::ptrdiff_t>((y - y0) * w + x));
        }
      }
      x += run;
    }
  }
  return fields;
}

}  // namespace

std::optional<Bridge::Core::GridCache> Bridge::Core::build_grid(std::uint32_t channel) {
  auto& cache = channel == kGridChannel ? bayes_tiles_ : ds_tiles_;
  const std::vector<std::string> names = channel == kGridChannel
                                             ? std::vector<std::string>{"probability"}
                                             : std::vector<std::string>{"belief", "plausibility", "conflict"};
  refresh(cache);
  if (cache.tiles.empty()) return std::nullopt;  // nothing observed yet
  // The tiles' bounding box, as GET /api/v1/grid answers by default.
  std::int64_t tx0 = std::numeric_limits<std::int64_t>::max(), ty0 = tx0,
               tx1 = std::numeric_limits<std::int64_t>::min(), ty1 = tx1;
  for (const auto& [index, tile] : cache.tiles) {
    tx0 = std::min(tx0, index.first);
    ty0 = std::min(ty0, index.second);
    tx1 = std::max(tx1, index.first);
    ty1 = std::max(ty1, index.second);
  }
  const double tile_m = cache.resolution_m * static_cast<double>(cache.tile_size);
  const fusion::GridGeometry region({static_cast<double>(tx0) * tile_m, static_cast<double>(ty0) * tile_m},
                                    cache.resolution_m, (tx1 - tx0 + 1) * cache.tile_size,
                                    (ty1 - ty0 + 1) * cache.tile_size);
  const auto k = coarsening_factor(region.width(), region.height(), options.max_grid_cells);
  std::vector<GridField> fields;
  fusion::GridGeometry sent = region;
  if (k == 1) {
    fields = assemble(cache.tiles, cache.tile_size, names.size(), names, region, 0, region.height());
  } else {
    // Pooled tile by tile straight into the coarse grid (each cell the largest known value of its k × k block, as
    // coarsened() does): the cost follows the tiles observed, not their bounding box, which two scans kilometres
    // apart make 10^12 cells.
    const std::int64_t cw = (region.width() + k - 1) / k, ch = (region.height() + k - 1) / k, t = cache.tile_size;
    for (const auto& name : names)
      fields.push_back({name, std::vector<float>(static_cast<std::size_t>(cw * ch), std::nanf(""))});
    for (const auto& [index, tile] : cache.tiles) {
      const auto& values = tile.second;
      if (values.size() < names.size() * static_cast<std::size_t>(t * t)) continue;
      const std::int64_t gx0 = (index.first - tx0) * t, gy0 = (index.second - ty0) * t;
      for (std::size_t l = 0; l < names.size(); ++l) {
        auto& out = fields[l].values;
        for (std::int64_t iy = 0; iy < t; ++iy) {
          const std::int64_t row = ((gy0 + iy) / k) * cw;
          const float* in = values.data() + l * static_cast<std::size_t>(t * t) + static_cast<std::size_t>(iy * t);
          for (std::int64_t ix = 0; ix < t; ++ix) {
            const float v = in[ix];
            float& cell = out[static_cast<std::size_t>(row + (gx0 + ix) / k)];
            if (!std::isnan(v) && (std::isnan(cell) || v > cell)) cell = v;
          }
        }
      }
    }
    sent = fusion::GridGeometry(region.origin_m(), region.resolution_m() * static_cast<double>(k), cw, ch);
  }
  auto payload = share(grid_message(sent, fields, unix_ns_now()));
  ++grid_messages;
  if (channel == kGridChannel) last_grid_bytes = payload->size();
  return GridCache{cache.revision, std::move(payload)};
}

void Bridge::Core::produce_grids() {
  for (const auto channel : {kGridChannel, kGridDsChannel}) {
    auto& cache = channel == kGridChannel ? grid_cache_ : ds_cache_;
    auto& published = channel == kGridChannel ? grid_published_ : ds_published_;
    if (!has_subscribers(channel)) {
      cache = {};  // stale from now on; a new subscriber reads the grid afresh
      published = -1;
      (channel == kGridChannel ? bayes_tiles_ : ds_tiles_).tiles.clear();  // its memory too
      continue;
    }
    auto built = build_grid(channel);
    if (!built) continue;  // nothing observed yet
    cache = std::move(*built);
    if (cache.revision != published) {
      published = cache.revision;
      publish(channel, cache.payload, unix_ns_now());
    }
  }
  grid_dirty_ = false;
}

void Bridge::Core::produce_scene(std::uint32_t channel) {
  const bool elements = channel == kElementsChannel;
  (elements ? elements_dirty_ : plan_dirty_) = false;
  auto& sent = elements ? elements_sent_ : plan_sent_;
  if (!has_subscribers(channel)) {
    sent.reset();  // a new subscriber starts from the whole scene anyway
    return;
  }
  const auto now = world.snapshot();
  if (!sent) {
    sent = now;
    return;
  }
  if (now->version == sent->version) return;
  const auto removed = world.removed_since(sent->version, now->version);
  const auto stamp = unix_ns_now();
  if (!removed) {  // the service no longer knows what went: the whole scene again
    sent = now;
    publish(channel, full_scene(channel), stamp);
    return;
  }
  std::vector<LineEntity> upserts;
  std::vector<std::string> deleted;
  if (elements) {
    for (const auto& [number, element] : now->elements)
      if (element.updated_version > sent->version) upserts.push_back(element_entity(element));
    deleted.assign(removed->elements.begin(), removed->elements.end());
  } else {
    for (const auto& object : now->objects)
      if (object.updated_version > sent->version) upserts.push_back(object_entity(object, world.world_options()));
    deleted.assign(removed->objects.begin(), removed->objects.end());
  }
  sent = now;
  if (!upserts.empty() || !deleted.empty())
    publish(channel, share(scene_update_message(upserts, deleted, false, stamp)), stamp);
}

// The whole scene of the snapshot the topic's updates go from, made once per version.
Payload Bridge::Core::full_scene(std::uint32_t channel) {
  const bool elements = channel == kElementsChannel;
  const auto& state = elements ? elements_sent_ : plan_sent_;
  auto& cache = elements ? elements_full_ : plan_full_;
  if (cache.second && cache.first == state->version) return cache.second;
  std::vector<LineEntity> entities;
  if (elements) {
    entities.reserve(state->elements.size());
    for (const auto& [number, element] : state->elements) entities.push_back(element_entity(element));
  } else {
    for (const auto& object : state->objects) entities.push_back(object_entity(object, world.world_options()));
  }
  cache = {state->version, share(scene_update_message(entities, {}, true, unix_ns_now()))};
  return cache.second;
}

std::uint32_t Bridge::Core::robot_channel(const std::string& id) {
  if (const auto it = robot_channels_.find(id); it != robot_channels_.end()) return it->second;
  std::lock_guard lock(clients_mutex);
  const auto channel_id = static_cast<std::uint32_t>(kFirstRobotChannel + robot_channels_.size());
  Channel channel{channel_id, "/robots/" + id + "/pose", "foxglove.PoseInFrame", schemas::pose_in_frame()};
  channels.push_back(channel);
  const auto advertise = advertise_json({channel});
  for (const auto& c : clients)
    if (auto client = c.lock()) client->push_text(advertise);
  robot_channels_.emplace(id, channel_id);
  return channel_id;
}

void Bridge::Core::produce_robots() {
  robots_dirty_ = false;
  std::vector<PlanarTransform> transforms;
  bool moved = false;
  for (const auto& robot : world.robots()) {
    if (!robot.pose) continue;
    const auto& pose = *robot.pose;
    const auto channel = robot_channel(robot.id);  // advertised even before anyone subscribes to it
    const auto stamp = unix_ns(pose.received_at_unix_s);
    transforms.push_back({std::string(kMapFrame), robot_frame(robot.id), pose.x, pose.y, pose.theta, stamp});
    const SentPose now{pose.x, pose.y, pose.theta, pose.received_at_unix_s};
    auto& last = robots_sent_[robot.id];
    if (last.received_at == now.received_at && last.x == now.x && last.y == now.y && last.theta == now.theta) continue;
    last = now;
    moved = true;
    publish(channel, share(pose_in_frame_message(pose.x, pose.y, pose.theta, stamp)), stamp);
  }
  // Every robot's transform in each message: a message is the whole tree, so a newer one may replace a queued one.
  if (moved) publish(kTfChannel, share(frame_transforms_message(transforms)), unix_ns_now());
}

void Bridge::Core::produce_decisions() {
  decisions_dirty_ = false;
  if (!has_subscribers(kDecisionsChannel)) {
    decision_cursor_ = world.snapshot()->last_decision_seq;
    return;
  }
  for (int page = 0; page < kDecisionPagesPerTurn; ++page) {
    const auto rows = world.decisions(decision_cursor_, kDecisionPage, std::nullopt);
    for (const auto& d : rows) {
      const auto stamp = unix_ns_now();
      publish(kDecisionsChannel, share(log_message(d, stamp)), stamp);
      decision_cursor_ = d.seq;
    }
    if (rows.size() < kDecisionPage) return;
  }
  decisions_dirty_ = true;  // more than a turn's worth: the rest next period
}

void Bridge::Core::serve(const InitialRequest& request) {
  const auto client = request.client.lock();
  if (!client) return;
  std::vector<Payload> payloads;
  const auto stamp = unix_ns_now();
  switch (request.channel) {
    case kGridChannel:
    case kGridDsChannel: {
      auto& cache = request.channel == kGridChannel ? grid_cache_ : ds_cache_;
      // The cache is current unless a scan came since it was made: then the grid is read afresh, once per pass of
      // the bridge's loop whatever the number of new subscriptions (each build can take tens of milliseconds).
      auto& built_pass = request.channel == kGridChannel ? grid_built_pass_ : ds_built_pass_;
      if (!cache.payload || (grid_dirty_ && built_pass != pass_)) {
        if (auto built = build_grid(request.channel)) cache = std::move(*built);
        built_pass = pass_;
      }
      if (cache.payload) payloads.push_back(cache.payload);
      break;
    }
    case kElementsChannel:
    case kPlanChannel: {
      // Bring the topic's other subscribers to now first, so that this one's whole scene and their changes start
      // from the same snapshot.
      auto& sent = request.channel == kElementsChannel ? elements_sent_ : plan_sent_;
      if (sent) produce_scene(request.channel);
      if (!sent) sent = world.snapshot();
      payloads.push_back(full_scene(request.channel));
      break;
    }
    case kTfChannel: {
      std::vector<PlanarTransform> all;
      for (const auto& robot : world.robots())
        if (robot.pose)
          all.push_back({std::string(kMapFrame), robot_frame(robot.id), robot.pose->x, robot.pose->y, robot.pose->theta,
                         unix_ns(robot.pose->received_at_unix_s)});
      if (!all.empty()) payloads.push_back(share(frame_transforms_message(all)));
      break;
    }
    case kDecisionsChannel: {
      if (has_subscribers(kDecisionsChannel))
        produce_decisions();  // the others first, as for the scenes
      else
        decision_cursor_ = world.snapshot()->last_decision_seq;
      const auto since =
          std::max<std::int64_t>(0, decision_cursor_ - static_cast<std::int64_t>(options.initial_decisions));
      for (const auto& d : world.decisions(since, options.initial_decisions, std::nullopt))
        if (d.seq <= decision_cursor_) payloads.push_back(share(log_message(d, stamp)));
      break;
    }
    default: {
      for (const auto& [id, channel] : robot_channels_)
        if (channel == request.channel)
          if (const auto robot = world.robot(id); robot && robot->pose)
            payloads.push_back(share(pose_in_frame_message(robot->pose->x, robot->pose->y, robot->pose->theta,
                                                           unix_ns(robot->pose->received_at_unix_s))));
      break;
    }
  }
  client->push_initial(request.subscription, request.channel, payloads, stamp);
}

// --- Bridge ---

Bridge::Bridge(const FoxgloveOptions& options, service::WorldPort& world, events::EventHub& hub,
               common::Diagnostics& diagnostics, ServerInfo info)
    : core_(std::make_shared<Core>(options, world, hub, diagnostics, std::move(info))) {
  core_->thread = std::thread([core = core_.get()] { core->run(); });
}

Bridge::~Bridge() { core_->stop(); }

std::shared_ptr<http::WebSocketEndpoint> Bridge::connect() { return std::make_shared<FoxgloveClient>(core_); }

BridgeStats Bridge::stats() const {
  BridgeStats s;
  {
    std::lock_guard lock(core_->clients_mutex);
    s.clients = static_cast<std::size_t>(
        std::count_if(core_->clients.begin(), core_->clients.end(), [](const auto& c) { return !c.expired(); }));
  }
  s.messages = core_->messages;
  s.superseded = core_->superseded;
  s.dropped = core_->dropped;
  s.resyncs = core_->resyncs;
  s.grid_messages = core_->grid_messages;
  s.last_grid_bytes = core_->last_grid_bytes;
  return s;
}

}  // namespace wm::foxglove
