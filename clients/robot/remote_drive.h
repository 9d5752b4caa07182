#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

// The robot side of driving from a browser: a WebSocket to wmd's GET /api/v1/robots/{id}/drive?role=robot, over
// which wmd relays its driver's commands {"v": m/s, "w": rad/s} (clamped to wmd's limits). Every command is handed
// to `apply` (the bridge's set_velocity); a stop is handed on when the connection is lost and when no command came
// for the hold time while the last one moved, so that a wmd that hangs or a half-open connection stops the robot as
// a driver that vanishes does. Reconnects every second while it is down.

namespace wm::robot {

/// Where wmd is, as RemoteDrive reads --server: http://host[:port] (an IPv6 host in brackets, kept in `host` without
/// them; port "80" when not given). nullopt for anything else.
struct DriveServer {
  std::string host;
  std::string port;
};
std::optional<DriveServer> parse_drive_server(const std::string& url);

struct RemoteDriveOptions {
  std::string server_url;  // http://host[:port]
  std::string robot_id;
  std::string token;  // wmd's --token; sent as Authorization: Bearer
  /// With no command for this long [s] while the last one moved, a stop. wmd forwards its driver's commands about
  /// ten times a second and holds its own 150 ms lease; this one is for wmd itself going quiet.
  double hold_s = 0.3;
  double reconnect_s = 1.0;
  std::function<void(const std::string&)> log;  // default: stderr
};

struct RemoteDriveStats {
  std::uint64_t connects = 0;
  std::uint64_t commands = 0;  // valid commands handed on
  std::uint64_t refused = 0;   // messages that were not a command (a stop was handed on)
  std::uint64_t hold_stops = 0;
  std::uint64_t disconnects = 0;
};

class RemoteDrive {
 public:
  /// Starts the connection thread. @throw std::invalid_argument for a URL that is not http://host[:port] or a bad
  /// robot id.
  RemoteDrive(RemoteDriveOptions options, std::function<void(double linear_mps, double angular_radps)> apply);
  /// Closes the connection and hands on a stop.
  ~RemoteDrive();
  RemoteDrive(const RemoteDrive&) = delete;
  RemoteDrive& operator=(const RemoteDrive&) = delete;

  bool connected() const;
  RemoteDriveStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wm::robot
