#include "server/foxglove/bridge.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <exception>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "server/foxglove/bridge_internal.h"

// The bridge's thread and its clients' registrations; the messages are made in bridge_grid.cpp and
// bridge_topics.cpp, each client's queue is bridge_client.cpp.
namespace wm::foxglove {
namespace {

// Like the read handlers (server/http/http_server.cpp): encoding megabytes of grid yields the CPU to ingest.
constexpr int kBridgeNice = 10;

}  // namespace

using internal::Clock;
using internal::FoxgloveClient;

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
    subscriber_ = hub.subscribe(
        [this] {
          {
            std::lock_guard lock(wake_mutex);
            events_pending = true;
          }
          wake_cv.notify_one();
        },
        /*wants_json=*/false);  // the kinds say what changed; the messages are made from the world
    // Whatever happened while nobody listened: everything is stale.
    grid_dirty_ = elements_dirty_ = plan_dirty_ = robots_dirty_ = decisions_dirty_ = true;
    grid_cache_ = ds_cache_ = {};
    grid_published_ = ds_published_ = -1;
    elements_sent_.reset();
    plan_sent_.reset();
    decision_cursor_ = world.map.snapshot()->last_decision_seq;
  } else if (!any && subscriber_) {
    hub.unsubscribe(subscriber_);
    subscriber_.reset();
  }
}

void Bridge::Core::take_events() {
  // Events only say what changed; the messages are made from the world itself.
  for (const auto& event : subscriber_->take()) {
    switch (event.kind) {
      case events::EventKind::scan:
        grid_dirty_ = robots_dirty_ = true;
        break;
      case events::EventKind::robot:
        robots_dirty_ = true;
        break;
      case events::EventKind::rules:  // the rules changed, not the map
        break;
      case events::EventKind::update:
      case events::EventKind::floorplan:
      case events::EventKind::placement:
      case events::EventKind::georeference:
        elements_dirty_ = plan_dirty_ = decisions_dirty_ = true;
        break;
      case events::EventKind::map_removed: {
        // The bridge's map was deleted: each client is told, then closed; the map goes when the last has gone.
        const auto map = info.metadata.find("map");
        const auto last = map_deleted_status(map == info.metadata.end() ? std::string_view() : map->second);
        for (const auto& client : live_clients()) client->push_last(last);
        break;
      }
      case events::EventKind::map_moved: {
        const auto map = info.metadata.find("map");
        const auto last = map_moved_status(map == info.metadata.end() ? std::string_view() : map->second);
        for (const auto& client : live_clients()) client->push_last(last);
        break;
      }
      case events::EventKind::change:
      case events::EventKind::resync:  // the hub dropped events for us: everything
        elements_dirty_ = plan_dirty_ = decisions_dirty_ = grid_dirty_ = robots_dirty_ = true;
        break;
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
std::string map_deleted_status(std::string_view map) {
  return status_json(StatusLevel::error, "the map" + (map.empty() ? std::string() : " '" + std::string(map) + "'") +
                                             " was deleted (GET /api/v1/maps lists the maps)");
}

std::string map_moved_status(std::string_view map) {
  return status_json(StatusLevel::error, "the map" + (map.empty() ? std::string() : " '" + std::string(map) + "'") +
                                             " moved to another node of the cluster: connect again (any node "
                                             "sends you on to its owner; GET /api/v1/maps names it)");
}

// --- Bridge ---

Bridge::Bridge(const FoxgloveOptions& options, service::WorldPorts world, events::EventHub& hub,
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
