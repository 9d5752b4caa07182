#pragma once

// Test-only: a private PostgreSQL server (tests/support/postgres.sh), started on first use by a test process and
// stopped when it exits; each test that uses it works in a schema of its own.
//
// A test target that includes this header defines WM_SOURCE_DIR.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "support/temp_dir.h"

#if !defined(WM_SOURCE_DIR)
#error "targets using support/postgres_server.h define WM_SOURCE_DIR"
#endif

namespace wm::testing {

class PostgresServer {
 public:
  /// Starts the server. @throw std::runtime_error with the script's message when it cannot.
  PostgresServer() {
    const std::string command = script() + " start " + dir_.path().string();
    FILE* out = ::popen(command.c_str(), "r");
    if (!out) throw std::runtime_error("cannot run " + command);
    char line[512] = {};
    const bool read = std::fgets(line, sizeof line, out) != nullptr;
    const int status = ::pclose(out);
    uri_ = read ? std::string(line) : std::string();
    while (!uri_.empty() && (uri_.back() == '\n' || uri_.back() == '\r')) uri_.pop_back();
    if (status != 0 || uri_.empty()) throw std::runtime_error("a test PostgreSQL server did not start: " + command);
  }
  ~PostgresServer() {
    const std::string command = script() + " stop " + dir_.path().string();
    [[maybe_unused]] const int ignored = std::system(command.c_str());
  }
  PostgresServer(const PostgresServer&) = delete;
  PostgresServer& operator=(const PostgresServer&) = delete;

  /// postgresql://wm@127.0.0.1:PORT/worldmodel
  const std::string& uri() const { return uri_; }
  /// Restarts the server: every open connection is cut. @throw std::runtime_error when it does not come back.
  void restart() const {
    const std::string command = script() + " restart " + dir_.path().string();
    if (std::system(command.c_str()) != 0) throw std::runtime_error("the test PostgreSQL server did not restart");
  }

 private:
  static std::string script() { return std::string(WM_SOURCE_DIR) + "/tests/support/postgres.sh"; }
  TempDir dir_;
  std::string uri_;
};

/// The test process's server, started on first call.
inline const PostgresServer& postgres() {
  static const auto server = std::make_unique<PostgresServer>();
  return *server;
}

/// A schema name of its own for the running test ("t_" and the test's name, lower case, [a-z0-9_]).
inline std::string schema_for(const std::string& test_name) {
  std::string name = "t_";
  for (const char c : test_name) {
    const char lower = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
    name += (lower >= 'a' && lower <= 'z') || (lower >= '0' && lower <= '9') ? lower : '_';
  }
  return name.substr(0, 63);
}

}  // namespace wm::testing
