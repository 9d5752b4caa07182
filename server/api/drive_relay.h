#pragma once

// Driving a robot from a browser through wmd: GET /api/v1/robots/{id}/drive is a WebSocket with two roles. The robot
// side (the bridge, ?role=robot) keeps one connection; a driver (the web viewer, ?role=driver, one at a time per
// robot) sends {"v": m/s, "w": rad/s} about ten times a second while a key or button is held. wmd clamps each
// command to its limits and passes it on; it commands a stop when the driver goes quiet for the hold time, at once
// when the driver sends a stop, sends anything that is not a command, or disconnects. The relay also keeps each
// robot's latest telemetry (from its pose reports) for GET /api/v1/robots and the driver. Nothing here is stored:
// after a restart a robot's telemetry is null until its next report.
#include <chrono>
#include <cstddef>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "server/api/http_types.h"
#include "server/http/websocket_endpoint.h"

namespace wm::api {

struct DriveOptions {
  /// Limits every driver command is clamped to [m/s], [rad/s] (--drive-max-speed, --drive-max-turn); the driver is
  /// told them. The Servosila's calibrated range is 0.4 m/s and 1.25 rad/s.
  double max_linear_mps = 0.4;
  double max_angular_radps = 1.25;
  /// The hold lease [ms] (--drive-hold-ms): with no driver command for this long, a moving robot is commanded to
  /// stop. The viewer sends every 100 ms while a key is held.
  int hold_ms = 150;
  /// A driver that sent nothing for this long [s] gives way to a new one (told "replaced" and closed): a browser whose
  /// connection went half-open, or a tab left open elsewhere, does not lock its robot until the transport's idle
  /// timeout. A driver that is driving (or stopped less than this ago) keeps the robot.
  double driver_takeover_s = 3.0;
  /// Largest message accepted from either side [bytes]; a larger one is refused (a stop and an error answer; the
  /// connection stays). Frames beyond the transport's own limit close it.
  std::size_t max_message_bytes = 4096;
  /// Messages a connection may have queued for sending; past it the connection is closed (a peer that stopped
  /// reading: its robot is stopped).
  std::size_t max_queued_messages = 256;
};

/// What a driver command says, or why it is refused. Parses {"v": number, "w": number} (nothing else, finite,
/// |v|, |w| ≤ 1e3 before clamping); the error text names the field.
struct DriveCommand {
  double linear_mps = 0.0;
  double angular_radps = 0.0;
};
std::optional<DriveCommand> parse_drive_command(std::string_view text, std::string& error);

/// The relay of every robot's drive connections and telemetry. Thread-safe; one lease thread.
class DriveRelay {
 public:
  explicit DriveRelay(const DriveOptions& options);
  ~DriveRelay();
  DriveRelay(const DriveRelay&) = delete;
  DriveRelay& operator=(const DriveRelay&) = delete;

  const DriveOptions& options() const;

  /// The endpoint of an upgrade the route table names as the drive WebSocket (authorize_drive allowed it);
  /// nullptr for any other target.
  std::shared_ptr<http::WebSocketEndpoint> connect(const Request& request);

  /// Keeps a robot's latest telemetry (parse_robot_telemetry's object) and tells its driver.
  void put_telemetry(const std::string& robot_id, nlohmann::json telemetry);

  /// {"telemetry": object | null, "telemetry_at": Unix s | null, "drive": {"robot_connected", "driver_connected",
  ///  "command": {"v", "w"}, "max_v", "max_w", "hold_ms"}} for GET /api/v1/robots; and whether the last telemetry
  /// reported a fault.
  nlohmann::json robot_live(const std::string& robot_id, bool& fault) const;

  struct Impl;  // shared with the connections' endpoints, which may outlive the relay by a moment

 private:
  std::shared_ptr<Impl> impl_;
};

/// For a WebSocket upgrade: 400 for a target that cannot be parsed, and for GET /api/v1/robots/{id}/drive with a bad
/// robot id or a role that is not "driver" or "robot"; nullopt otherwise. Never throws.
std::optional<Response> authorize_drive(const Request& request);

}  // namespace wm::api
