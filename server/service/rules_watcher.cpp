#include "server/service/rules_watcher.h"

#include <poll.h>
#include <sys/inotify.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>

namespace wm::service {
namespace {

bool is_rule_file(const char* name) {
  const std::string n(name);
  return !n.empty() && n.front() != '.' && n.size() > 3 && n.compare(n.size() - 3, 3, ".pl") == 0;
}

// Editors save in place (CLOSE_WRITE) or by rename (MOVED_TO); deletions change the rule set too. A directory
// created or removed below a watched one is seen through CREATE / DELETE / MOVED_*.
constexpr auto kMask = IN_CLOSE_WRITE | IN_MOVED_TO | IN_MOVED_FROM | IN_DELETE | IN_CREATE;

}  // namespace

RulesWatcher::RulesWatcher(std::vector<std::filesystem::path> dirs, std::function<void()> on_change,
                           std::chrono::milliseconds settle)
    : dirs_(std::move(dirs)), watches_(dirs_.size(), -1), on_change_(std::move(on_change)), settle_(settle) {
  if (dirs_.empty()) throw std::runtime_error("RulesWatcher: no directory to watch");
  inotify_fd_ = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  if (inotify_fd_ < 0) throw std::runtime_error(std::string("RulesWatcher: inotify_init1: ") + std::strerror(errno));
  watches_[0] = ::inotify_add_watch(inotify_fd_, dirs_[0].c_str(), kMask);
  if (watches_[0] < 0) {
    const std::string error = std::strerror(errno);
    ::close(inotify_fd_);
    throw std::runtime_error("RulesWatcher: cannot watch '" + dirs_[0].string() + "': " + error);
  }
  watch_the_missing();
  thread_ = std::thread([this] { loop(); });
}

RulesWatcher::~RulesWatcher() {
  stopping_ = true;
  thread_.join();
  ::close(inotify_fd_);
}

bool RulesWatcher::watch_the_missing() {
  bool added = false;
  for (std::size_t i = 0; i < dirs_.size(); ++i) {
    if (watches_[i] >= 0) continue;
    std::error_code ec;
    if (!std::filesystem::is_directory(dirs_[i], ec)) continue;
    watches_[i] = ::inotify_add_watch(inotify_fd_, dirs_[i].c_str(), kMask);
    added = added || watches_[i] >= 0;
  }
  return added;
}

bool RulesWatcher::matters(int watch, const char* name, bool is_dir) const {
  const auto at = std::find(watches_.begin(), watches_.end(), watch);
  if (at == watches_.end()) return false;
  const auto i = static_cast<std::size_t>(at - watches_.begin());
  // Rule files count in the first directory and the last; a directory only where it is the next one watched
  // (another map's directory appearing beside this map's is not this map's change).
  if (is_dir) return i + 1 < dirs_.size() && dirs_[i + 1].filename() == name;
  return (i == 0 || i + 1 == dirs_.size()) && is_rule_file(name);
}

void RulesWatcher::loop() {
  alignas(inotify_event) std::array<char, 4096> buffer;
  bool pending = false;
  auto quiet_since = std::chrono::steady_clock::now();
  while (!stopping_) {
    pollfd fd{inotify_fd_, POLLIN, 0};
    const int ready = ::poll(&fd, 1, 50);  // short timeout: notice stopping_ and the settle time
    bool changed = false;
    if (ready > 0) {
      for (;;) {
        const auto n = ::read(inotify_fd_, buffer.data(), buffer.size());
        if (n <= 0) break;
        for (char* p = buffer.data(); p < buffer.data() + n;) {
          const auto* event = reinterpret_cast<const inotify_event*>(p);
          if (event->mask & IN_IGNORED) {
            // A watched directory went away (its watch with it): its files are no longer rules.
            for (auto& watch : watches_)
              if (watch == event->wd) watch = -1;
            changed = true;
          } else if (event->len > 0) {
            changed = changed || matters(event->wd, event->name, (event->mask & IN_ISDIR) != 0);
          }
          p += sizeof(inotify_event) + event->len;
        }
      }
    }
    // A directory that appeared since: watched from now, and what is already in it counts.
    if (ready > 0 && watch_the_missing()) changed = true;
    if (changed) {
      pending = true;
      quiet_since = std::chrono::steady_clock::now();
    }
    if (pending && std::chrono::steady_clock::now() - quiet_since >= settle_) {
      pending = false;
      on_change_();
    }
  }
}

}  // namespace wm::service
