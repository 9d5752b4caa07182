#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace wm::events {

/// What an event says changed, so that a subscriber in the process (the Foxglove bridge) acts on it without parsing
/// the JSON that WebSocket clients get.
enum class EventKind {
  scan,          // a scan went into the grid (its returns, the robot's pose)
  update,        // a commit changed the map (elements, objects, decisions)
  floorplan,     // a plan was loaded
  placement,     // the plan was moved
  georeference,  // the world frame's georeference changed
  rules,         // the rule files were reloaded (the map did not change)
  robot,         // a robot's pose or status
  change,        // a change was accepted, rejected or undone
  resync,        // this subscriber fell behind and lost events: everything is stale
  map_removed,   // the map was deleted: nothing more comes
  map_moved,     // another node of the cluster serves the map now ("owner": its URL): nothing more comes from here
};

/// One event as a subscriber gets it: its kind, and its JSON text with "seq" spliced in.
struct Event {
  EventKind kind;
  std::string json;
};

/// Fan-out of events (JSON texts) to live subscribers, e.g. the web viewer's WebSockets.
/// publish() never blocks on a subscriber: each has a bounded queue, and one that falls behind loses its
/// queue and gets a single {"type":"resync"} event instead, after which it re-reads the REST API. So a
/// slow page can never slow ingest.
class EventHub {
 public:
  class Subscriber {
   public:
    /// Everything queued since the last call, oldest first.
    std::vector<Event> take();
    /// Events dropped for this subscriber so far (each overflow replaces the queue by one resync).
    std::uint64_t dropped() const { return dropped_.load(); }

   private:
    friend class EventHub;
    Subscriber(std::size_t capacity, std::function<void()> wake, bool wants_json)
        : capacity_(capacity), wake_(std::move(wake)), wants_json_(wants_json) {}
    void push(EventKind kind, const std::string& json);

    const std::size_t capacity_;
    const std::function<void()> wake_;
    const bool wants_json_;
    std::mutex mutex_;
    std::deque<Event> queue_;
    bool overflowed_ = false;
    std::atomic<std::uint64_t> dropped_{0};
  };

  explicit EventHub(std::size_t queue_capacity = 1024) : capacity_(queue_capacity) {}

  /// `wake` is called (on the publishing thread, must not block) when events were queued. A subscriber that does
  /// not want the JSON (one in the process that acts on the kind alone) may get "{}" with the seq only: a publisher
  /// builds the JSON only when json_subscriber_count() says someone reads it.
  std::shared_ptr<Subscriber> subscribe(std::function<void()> wake, bool wants_json = true);
  void unsubscribe(const std::shared_ptr<Subscriber>& subscriber);
  /// Stamps the event with the hub's next sequence number ("seq", so pages can see gaps) and queues it for
  /// every subscriber. `event_json` must be a JSON object text without "seq"; it is spliced in.
  /// @throw std::invalid_argument when it is not a JSON object text.
  void publish(EventKind kind, const std::string& event_json);
  std::size_t subscriber_count() const;
  /// Both counts as of one instant, under one lock (what a publisher asks before it makes an event).
  struct Listeners {
    std::size_t subscribers = 0;
    std::size_t json_subscribers = 0;
  };
  Listeners listeners() const;
  /// Subscribers that read the events' JSON (the WebSocket clients).
  std::size_t json_subscriber_count() const;
  std::uint64_t last_seq() const { return seq_.load(); }

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Subscriber>> subscribers_;
  std::atomic<std::uint64_t> seq_{0};
};

}  // namespace wm::events
