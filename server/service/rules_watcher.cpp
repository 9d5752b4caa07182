#include "server/service/rules_watcher.h"

#include <poll.h>
#include <sys/inotify.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

namespace wm::service {
namespace {

bool is_rule_file(const char* name) {
  const std::string n(name);
  return !n.empty() && n.front() != '.' && n.size() > 3 && n.compare(n.size() - 3, 3, ".pl") == 0;
}

}  // namespace

RulesWatcher::RulesWatcher(const std::filesystem::path& dir, std::function<void()> on_change,
                           std::chrono::milliseconds settle)
    : on_change_(std::move(on_change)), settle_(settle) {
  inotify_fd_ = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  if (inotify_fd_ < 0) throw std::runtime_error(std::string("RulesWatcher: inotify_init1: ") + std::strerror(errno));
  // Editors save in place (CLOSE_WRITE) or by rename (MOVED_TO); deletions change the rule set too.
  const auto mask = IN_CLOSE_WRITE | IN_MOVED_TO | IN_MOVED_FROM | IN_DELETE | IN_CREATE;
  if (::inotify_add_watch(inotify_fd_, dir.c_str(), mask) < 0) {
    const std::string error = std::strerror(errno);
    ::close(inotify_fd_);
    throw std::runtime_error("RulesWatcher: cannot watch '" + dir.string() + "': " + error);
  }
  thread_ = std::thread([this] { loop(); });
}

RulesWatcher::~RulesWatcher() {
  stopping_ = true;
  thread_.join();
  ::close(inotify_fd_);
}

void RulesWatcher::loop() {
  alignas(inotify_event) std::array<char, 4096> buffer;
  bool pending = false;
  auto quiet_since = std::chrono::steady_clock::now();
  while (!stopping_) {
    pollfd fd{inotify_fd_, POLLIN, 0};
    const int ready = ::poll(&fd, 1, 50);  // short timeout: notice stopping_ and the settle time
    if (ready > 0) {
      for (;;) {
        const auto n = ::read(inotify_fd_, buffer.data(), buffer.size());
        if (n <= 0) break;
        for (char* p = buffer.data(); p < buffer.data() + n;) {
          const auto* event = reinterpret_cast<const inotify_event*>(p);
          if (event->len > 0 && is_rule_file(event->name)) {
            pending = true;
            quiet_since = std::chrono::steady_clock::now();
          }
          p += sizeof(inotify_event) + event->len;
        }
      }
    }
    if (pending && std::chrono::steady_clock::now() - quiet_since >= settle_) {
      pending = false;
      on_change_();
    }
  }
}

}  // namespace wm::service
