#include "server/events/event_hub.h"

#include <algorithm>
#include <stdexcept>

namespace wm::events {

std::vector<Event> EventHub::Subscriber::take() {
  std::lock_guard lock(mutex_);
  std::vector<Event> events(std::make_move_iterator(queue_.begin()), std::make_move_iterator(queue_.end()));
  queue_.clear();
  overflowed_ = false;
  return events;
}

void EventHub::Subscriber::push(EventKind kind, const std::string& json) {
  {
    std::lock_guard lock(mutex_);
    if (overflowed_) {
      dropped_.fetch_add(1);
      return;  // already told to resync: nothing else matters until it has read that
    }
    if (queue_.size() >= capacity_) {
      dropped_.fetch_add(queue_.size() + 1);
      queue_.clear();
      queue_.push_back({EventKind::resync,
                        R"({"type":"resync","reason":"this client fell behind; re-read the map from the REST API"})"});
      overflowed_ = true;
    } else {
      queue_.push_back({kind, json});
    }
  }
  wake_();
}

std::shared_ptr<EventHub::Subscriber> EventHub::subscribe(std::function<void()> wake, bool wants_json) {
  auto subscriber = std::shared_ptr<Subscriber>(new Subscriber(capacity_, std::move(wake), wants_json));
  std::lock_guard lock(mutex_);
  subscribers_.push_back(subscriber);
  return subscriber;
}

void EventHub::unsubscribe(const std::shared_ptr<Subscriber>& subscriber) {
  std::lock_guard lock(mutex_);
  subscribers_.erase(std::remove(subscribers_.begin(), subscribers_.end(), subscriber), subscribers_.end());
}

void EventHub::publish(EventKind kind, const std::string& event_json) {
  if (event_json.size() < 2 || event_json.front() != '{' || event_json.back() != '}')
    throw std::invalid_argument("EventHub::publish: expected a JSON object text");
  std::vector<std::shared_ptr<Subscriber>> targets;
  std::uint64_t seq = 0;
  {
    std::lock_guard lock(mutex_);
    seq = ++seq_;  // under the lock: every subscriber sees the events in seq order
    targets = subscribers_;
    const std::string stamped =
        "{\"seq\":" + std::to_string(seq) + (event_json.size() > 2 ? "," : "") + event_json.substr(1);
    for (const auto& s : targets) s->push(kind, stamped);
  }
}

std::size_t EventHub::subscriber_count() const {
  std::lock_guard lock(mutex_);
  return subscribers_.size();
}

EventHub::Listeners EventHub::listeners() const {
  std::lock_guard lock(mutex_);
  Listeners l;
  l.subscribers = subscribers_.size();
  for (const auto& s : subscribers_) l.json_subscribers += s->wants_json_ ? 1 : 0;
  return l;
}

std::size_t EventHub::json_subscriber_count() const {
  std::lock_guard lock(mutex_);
  return static_cast<std::size_t>(
      std::count_if(subscribers_.begin(), subscribers_.end(), [](const auto& s) { return s->wants_json_; }));
}

}  // namespace wm::events
