#include <algorithm>
#include <string>

#include "server/foxglove/bridge_internal.h"

// One client's side of the bridge: the protocol messages it sends (subscribe, unsubscribe), its
// subscriptions and its bounded queue.
namespace wm::foxglove::internal {
namespace {

constexpr std::size_t kMaxEchoedOp = 64;                // characters of a client's text quoted back
constexpr std::size_t kMaxQueuedTextBytes = 256 << 10;  // statuses waiting for a client that does not read

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

}  // namespace

void FoxgloveClient::open(std::function<void()> wake) {
  {
    std::lock_guard lock(mutex_);
    wake_ = std::move(wake);
  }
  if (core_->add_client(shared_from_this())) return;
  std::function<void()> wake_now;
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(
        {{false,
          status_json(StatusLevel::error, "too many Foxglove clients: this server serves " +
                                              std::to_string(core_->options.max_clients) + " at once; try again later"),
          nullptr, true},
         0,
         false});
    wake_now = wake_;
  }
  if (wake_now) wake_now();
}

void FoxgloveClient::receive(std::string_view message, bool binary) {
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

std::vector<http::WebSocketFrame> FoxgloveClient::take() {
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

void FoxgloveClient::close() {
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

std::size_t FoxgloveClient::push_data(std::uint32_t channel, const Payload& payload, std::uint64_t stamp_ns) {
  std::size_t queued = 0;
  std::function<void()> wake;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, sub] : subscriptions_)
      if (sub.active && sub.channel == channel && push_data_locked(id, payload, stamp_ns, delivery_of(channel), false))
        ++queued;
    if (queued > 0) wake = wake_;
  }
  if (wake) wake();
  return queued;
}

std::size_t FoxgloveClient::push_initial(std::uint32_t subscription, std::uint32_t channel,
                                         const std::vector<Payload>& payloads, std::uint64_t stamp_ns) {
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

void FoxgloveClient::push_text(std::string text) {
  std::function<void()> wake;
  {
    std::lock_guard lock(mutex_);
    if (closed_ || ending_) return;
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

void FoxgloveClient::push_last(std::string text) {
  std::function<void()> wake;
  {
    std::lock_guard lock(mutex_);
    if (closed_ || ending_) return;
    ending_ = true;
    http::WebSocketFrame last{false, std::move(text), nullptr};
    last.close_after = true;
    queue_.push_back({std::move(last), 0, false});
    wake = wake_;
  }
  if (wake) wake();
}

bool FoxgloveClient::subscribed(std::uint32_t channel) const {
  std::lock_guard lock(mutex_);
  if (behind_ || closed_ || ending_) return false;
  return std::any_of(subscriptions_.begin(), subscriptions_.end(),
                     [&](const auto& entry) { return entry.second.active && entry.second.channel == channel; });
}

bool FoxgloveClient::push_data_locked(std::uint32_t subscription, const Payload& payload, std::uint64_t stamp_ns,
                                      Delivery delivery, bool initial) {
  if (closed_ || ending_) return false;
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

void FoxgloveClient::fall_behind() {
  const auto lost = static_cast<std::uint64_t>(
      std::count_if(queue_.begin(), queue_.end(), [](const Queued& q) { return q.frame.binary; }));
  std::erase_if(queue_, [](const Queued& q) { return q.frame.binary; });
  counted_bytes_ = 0;
  counted_messages_ = 0;
  dropped_ += lost + 1;
  core_->dropped += lost + 1;
  behind_ = true;
}

}  // namespace wm::foxglove::internal
