#pragma once

// What the bridge's sources share (the UDP endpoint, the rate-limited log, option checks); not public.

#include <netinet/in.h>
#include <sys/socket.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <string>

#include "clients/robot/servosila_bridge.h"

namespace wm::robot::internal {

using Clock = std::chrono::steady_clock;

inline Clock::duration to_duration(double seconds) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

/// Logs the first occurrence of each kind of problem, then at most one line per interval, saying how many were
/// left out in between.
class RateLimitedLog {
 public:
  RateLimitedLog(std::function<void(const std::string&)> sink, double interval_s)
      : sink_(std::move(sink)), interval_(to_duration(interval_s)) {}

  void always(const std::string& message) const { sink_(message); }

  void limited(const std::string& kind, const std::string& message, Clock::time_point now) {
    Entry& e = entries_[kind];
    if (e.logged && now - e.last < interval_) {
      ++e.suppressed;
      return;
    }
    std::string line = message;
    if (e.suppressed > 0) line += " (" + std::to_string(e.suppressed) + " more like it not logged)";
    e = Entry{true, now, 0};
    sink_(line);
  }

 private:
  struct Entry {
    bool logged = false;
    Clock::time_point last;
    std::uint64_t suppressed = 0;
  };
  std::function<void(const std::string&)> sink_;
  Clock::duration interval_;
  std::map<std::string, Entry> entries_;
};

struct Endpoint {
  sockaddr_storage address{};
  socklen_t length = 0;
};

Endpoint resolve(const std::string& host, std::uint16_t port);
std::string to_string(const sockaddr_storage& a);
bool same_peer(const sockaddr_storage& a, const sockaddr_storage& b, bool compare_port);

// @throw std::invalid_argument for options out of range.
void validate(const BridgeOptions& o);
std::function<void(const std::string&)> default_log();

}  // namespace wm::robot::internal
