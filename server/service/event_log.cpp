#include "server/service/event_log.h"

#include <string>

namespace wm::service {

EventLog::Commit& EventLog::Commit::operator=(Commit&& other) noexcept {
  if (this != &other) {
    close();
    log_ = std::exchange(other.log_, nullptr);
    place_ = std::move(other.place_);
  }
  return *this;
}

void EventLog::Commit::add(events::EventKind kind, const std::function<nlohmann::json()>& make_json) {
  if (!log_) return;
  try {
    // The JSON only for those who read it (WebSocket clients); the bridge and the export act on the kind.
    place_->events.emplace_back(kind, !place_->wants_json
                                          ? std::string("{}")
                                          : make_json().dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  } catch (const std::exception& e) {
    log_->diagnostics_.report(common::Severity::warning, "events", std::string("event not made: ") + e.what());
  }
}

void EventLog::Commit::close() {
  if (!log_) return;
  std::exchange(log_, nullptr)->close(place_);
  place_.reset();
}

EventLog::Commit EventLog::begin() {
  if (!hub_) return {};
  const auto listeners = hub_->listeners();
  if (listeners.subscribers == 0) return {};
  auto place = std::make_shared<Place>();
  place->wants_json = listeners.json_subscribers > 0;
  std::lock_guard lock(mutex_);
  places_.push_back(place);
  return Commit(this, std::move(place));
}

void EventLog::publish(events::EventKind kind, const std::function<nlohmann::json()>& make_json) {
  auto commit = begin();
  commit.add(kind, make_json);
  commit.close();
}

std::size_t EventLog::waiting() const {
  std::lock_guard lock(mutex_);
  return places_.size();
}

void EventLog::close(const std::shared_ptr<Place>& place) {
  std::lock_guard lock(mutex_);
  place->closed = true;
  while (!places_.empty() && places_.front()->closed) {
    for (const auto& [kind, json] : places_.front()->events) {
      try {
        hub_->publish(kind, json);
      } catch (const std::exception& e) {
        diagnostics_.report(common::Severity::warning, "events", std::string("event not published: ") + e.what());
      }
    }
    places_.pop_front();
  }
}

}  // namespace wm::service
