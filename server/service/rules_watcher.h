#pragma once

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <thread>
#include <vector>

namespace wm::service {

/// Watches rules directories (inotify) and calls `on_change` once the *.pl files have been quiet for `settle`
/// after a change, so that an editor's save (write, rename, chmod...) triggers one reload. Files starting with
/// '.' (editor swap files) and other extensions are ignored.
///
/// The first directory must exist. The others are a chain below it that may come and go (a map's own rules
/// directory and the ones between: `rules/maps`, `rules/maps/floor2`): each is watched from when it appears,
/// which counts as a change (files may already be in it), and its removal is a change too. Rule files count in
/// the first directory and the last only.
class RulesWatcher {
 public:
  /// @throw std::runtime_error when the first directory cannot be watched.
  RulesWatcher(std::vector<std::filesystem::path> dirs, std::function<void()> on_change,
               std::chrono::milliseconds settle = std::chrono::milliseconds(150));
  ~RulesWatcher();
  RulesWatcher(const RulesWatcher&) = delete;
  RulesWatcher& operator=(const RulesWatcher&) = delete;

 private:
  void loop();
  // Adds a watch to each directory that has none and exists now; whether one was added.
  bool watch_the_missing();
  // Whether an event about `name` in the directory watched by `watch` changes the rules.
  bool matters(int watch, const char* name, bool is_dir) const;

  std::vector<std::filesystem::path> dirs_;
  std::vector<int> watches_;  // per directory: its watch descriptor, -1 while it has none
  std::function<void()> on_change_;
  std::chrono::milliseconds settle_;
  int inotify_fd_ = -1;
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

}  // namespace wm::service
