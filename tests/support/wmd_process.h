#pragma once

// Test-only: starts the real wmd binary on a free port and stops it again.
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "support/temp_dir.h"

extern char** environ;

namespace wm::testing {

/// The wmd server as a child process. The constructor returns once wmd printed the port it listens on.
class WmdProcess {
 public:
  explicit WmdProcess(std::vector<std::string> args) {
    int out[2];
    if (::pipe(out) != 0) throw std::runtime_error("pipe failed");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, out[0]);
    args.insert(args.begin(), WM_WMD_PATH);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, WM_WMD_PATH, &actions, nullptr, argv.data(), environ) != 0)
      throw std::runtime_error("cannot start " WM_WMD_PATH);
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    stdout_fd_ = out[0];
    const std::string marker = "listening on http://";
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (output_.find(marker) == std::string::npos || output_.find('\n', output_.find(marker)) == std::string::npos) {
      if (std::chrono::steady_clock::now() > deadline) throw std::runtime_error("wmd did not start: " + output_);
      if (!read_some(200)) {
        int status = 0;
        if (::waitpid(pid_, &status, WNOHANG) == pid_) {
          pid_ = -1;
          throw std::runtime_error("wmd exited at start: " + output_);
        }
      }
    }
    const auto start = output_.find(marker) + marker.size();
    const auto colon = output_.find(':', start);
    port_ = std::stoi(output_.substr(colon + 1));
  }

  ~WmdProcess() { stop(); }
  WmdProcess(const WmdProcess&) = delete;
  WmdProcess& operator=(const WmdProcess&) = delete;

  int port() const { return port_; }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  const std::string& output() const { return output_; }
  pid_t pid() const { return pid_; }

  /// SIGTERM and wait; returns the exit status (or -1 when not running).
  int stop() { return stop_with(SIGTERM); }
  /// SIGKILL: a crash, no clean shutdown.
  void crash() { stop_with(SIGKILL); }

 private:
  int stop_with(int signal) {
    if (pid_ <= 0) return -1;
    ::kill(pid_, signal);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    while (read_some(0)) {
    }
    ::close(stdout_fd_);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  bool read_some(int timeout_ms) {
    pollfd p{stdout_fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return false;
    char buffer[4096];
    const auto n = ::read(stdout_fd_, buffer, sizeof buffer);
    if (n <= 0) return false;
    output_.append(buffer, static_cast<std::size_t>(n));
    return true;
  }

  pid_t pid_ = -1;
  int stdout_fd_ = -1;
  int port_ = 0;
  std::string output_;
};

/// Runs a command, returns its exit status and what it printed on stdout and stderr.
struct CommandResult {
  int status = -1;
  std::string output;
};

inline CommandResult run_command(const std::string& command) {
  CommandResult r;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) throw std::runtime_error("popen failed");
  char buffer[4096];
  while (auto n = std::fread(buffer, 1, sizeof buffer, pipe)) r.output.append(buffer, n);
  const int status = ::pclose(pipe);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace wm::testing
