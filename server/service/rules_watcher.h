#pragma once

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <thread>

namespace wm::service {

/// Watches a rules directory (inotify) and calls `on_change` once the *.pl files have been quiet for
/// `settle` after a change, so that an editor's save (write, rename, chmod...) triggers one reload.
/// Files starting with '.' (editor swap files) and other extensions are ignored.
class RulesWatcher {
 public:
  /// @throw std::runtime_error when the directory cannot be watched.
  RulesWatcher(const std::filesystem::path& dir, std::function<void()> on_change,
               std::chrono::milliseconds settle = std::chrono::milliseconds(150));
  ~RulesWatcher();
  RulesWatcher(const RulesWatcher&) = delete;
  RulesWatcher& operator=(const RulesWatcher&) = delete;

 private:
  void loop();

  std::function<void()> on_change_;
  std::chrono::milliseconds settle_;
  int inotify_fd_ = -1;
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

}  // namespace wm::service
