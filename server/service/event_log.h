#pragma once

#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "common/diagnostics.h"
#include "server/events/event_hub.h"

namespace wm::service {

/// Publishes the live events of commits to the hub in commit order, the events of one commit together and from one
/// thread. A commit takes its place when it commits (on the writer, so places follow the commits), its stages add
/// events as they finish (the map update on the writer, the grid region on the grid thread), and its events go out
/// when it and every commit before it are closed: all by the thread that closes the last of them. So no subscriber
/// sees a later commit's event before an earlier one's, or two commits' events interleaved.
class EventLog {
  struct Place;

 public:
  /// The events of one commit. Closing it (or destroying it: a value the network drops when the server stops) lets
  /// them go.
  class Commit {
   public:
    Commit() = default;
    Commit(Commit&& other) noexcept : log_(std::exchange(other.log_, nullptr)), place_(std::move(other.place_)) {}
    Commit& operator=(Commit&& other) noexcept;
    Commit(const Commit&) = delete;
    Commit& operator=(const Commit&) = delete;
    ~Commit() { close(); }

    /// Adds an event. `make_json` runs now, and only when a subscriber read the JSON as the commit began (else the
    /// event is "{}" with its kind); an exception from it is reported and the event left out.
    void add(events::EventKind kind, const std::function<nlohmann::json()>& make_json);
    /// Done: its events go out as soon as every commit before it is closed. Closing twice does nothing.
    void close();

   private:
    friend class EventLog;
    Commit(EventLog* log, std::shared_ptr<Place> place) : log_(log), place_(std::move(place)) {}
    EventLog* log_ = nullptr;  // null: nobody listened when it began, its events are not made
    std::shared_ptr<Place> place_;
  };

  /// `hub` may be null (no live clients: every commit is inert). `diagnostics` hears of events not published.
  EventLog(events::EventHub* hub, common::Diagnostics& diagnostics) : hub_(hub), diagnostics_(diagnostics) {}
  EventLog(const EventLog&) = delete;
  EventLog& operator=(const EventLog&) = delete;

  /// The next place in commit order. Inert (nothing made, nothing held up) when nobody subscribes.
  Commit begin();
  /// A commit of one event, closed at once.
  void publish(events::EventKind kind, const std::function<nlohmann::json()>& make_json);
  /// Commits begun and not yet published (closed ones waiting behind an open one count too).
  std::size_t waiting() const;

 private:
  struct Place {
    std::vector<std::pair<events::EventKind, std::string>> events;  // written only by its Commit, until closed
    bool wants_json = false;  // a subscriber read JSON when the commit began: its events' JSON is made
    bool closed = false;      // under mutex_
  };
  void close(const std::shared_ptr<Place>& place);

  events::EventHub* const hub_;
  common::Diagnostics& diagnostics_;
  mutable std::mutex mutex_;  // held while publishing, so commits go out one after another
  std::deque<std::shared_ptr<Place>> places_;
};

}  // namespace wm::service
