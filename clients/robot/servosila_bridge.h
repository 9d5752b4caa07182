#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "clients/robot/odometry.h"
#include "clients/robot/servosila_protocol.h"
#include "clients/robot/servosila_units.h"

// The bridge between a Servosila Engineer (UDP, PROTOCOL.md) and the world model (HTTP): it drives the robot with
// velocity commands and reports the robot's odometry as its pose. Safety first: whenever the bridge is in doubt —
// at exit, on a signal (the executable's job, through halt()), when the robot's telemetry stops, on a NaN
// command — it sends a stop (both platform axes 0), and it keeps sending it five times a second.

namespace wm::robot {

/// Where the robot's odometry comes from. An honest note: the seed (the paper on the Engineer) reports that the
/// real robot's chassis motors give no telemetry, and its authors dead-reckon distance as speed × time. So on real
/// hardware the track records this bridge would integrate are probably absent (or do not count), and `automatic`
/// falls back to integrating the commanded velocity — with the covariance model of OdometryOptions, which is then
/// optimistic: it knows nothing of slip, of the 3 % uncertainty of the constants or of turns that are slower than
/// the angular constant says. Only the simulator is known to report track counts.
enum class OdometrySource {
  automatic,  // decided at the first telemetry packet: tracks when it carries both track records, else commanded
  tracks,     // the track motors' position counts (DiffDriveOdometry::update)
  commanded,  // dead reckoning from the velocity sent (DiffDriveOdometry::advance), as the seed's authors do
};
const char* to_string(OdometrySource source);

/// A pose to report, with what the bridge knows of the robot's motion.
struct PoseReport {
  OdometryPose pose;
  /// False only when the command is zero and the odometry has been seen standing still since (tracks: a telemetry
  /// packet that arrived after the stop showed no motion; commanded: a zero command was sent).
  bool moving = true;
  double stamp_unix_s = 0.0;  // when the pose was taken (system clock)
  /// The motor records of the last valid telemetry packet (empty before the first): raw amps, fault flags and
  /// counters, as the robot sent them. The protocol has no temperatures.
  std::vector<MotorRecord> motors;
  bool has_telemetry = false;
};

/// Where poses go. The bridge calls publish() from one thread at a time (its reporter thread, then at shutdown the
/// thread that shuts it down), never while holding its own lock, so an implementation may block.
class PoseSink {
 public:
  virtual ~PoseSink() = default;
  /// @throw std::exception on failure; the bridge counts and logs it and carries on.
  virtual void publish(const PoseReport& report) = 0;
};

/// The body of `PUT /api/v1/robots/{id}/pose` for a report: {"x", "y", "theta", "cov": 3×3, "stamp", "state",
/// "telemetry"?: {"motors": [{"id", "state", "mode", "current" (the raw amps field), "temperature": null (the
/// protocol has none), "fault", "faults", "status_bits"}], "current_unit": "raw", "temperature_unit": "none"}}.
std::string pose_report_json(const PoseReport& report);

/// PUTs each report to a wmd server (`PUT /api/v1/robots/{id}/pose`, `Authorization: Bearer` when a token is set).
class HttpPoseSink : public PoseSink {
 public:
  /// @throw std::invalid_argument for a robot id that is not 1 to 128 of A-Z a-z 0-9 . _ : -;
  ///        wm::client::ConnectionError for a URL that is not http://host[:port].
  HttpPoseSink(const std::string& server_url, const std::string& robot_id, const std::string& token = {},
               std::chrono::seconds timeout = std::chrono::seconds(2));
  ~HttpPoseSink() override;
  /// @throw wm::client::ConnectionError when the server cannot be reached; std::runtime_error for a non-2xx answer.
  void publish(const PoseReport& report) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// True for 1 to 128 of A-Z a-z 0-9 . _ : - (what wmd accepts as a robot id).
bool valid_robot_id(std::string_view id);

/// "HOST:PORT", "[V6ADDR]:PORT" or "HOST" (port = default_port).
/// @throw std::invalid_argument for an empty host or a port that is not 1..65535.
struct HostPort {
  std::string host;
  std::uint16_t port = 0;
};
HostPort parse_host_port(std::string_view text, std::uint16_t default_port);

struct BridgeOptions {
  /// The robot: a numeric address or a host name, and its UDP port. The authors' library sends to 10.42.0.1
  /// port 10000 (PROTOCOL.md).
  std::string robot_host = "10.42.0.1";
  std::uint16_t robot_port = 10000;
  /// The local UDP port control packets go from and telemetry comes to (0: any free port). The robot answers the
  /// sender of the control packets, so this only matters behind a firewall.
  std::uint16_t listen_port = 0;
  /// Telemetry is accepted only from the robot's address and port. Set this when the robot answers from another
  /// port than the one it listens on (the address must still match).
  bool accept_any_robot_port = false;
  /// Control packets: one every period [s] (the operator's five a second), plus one at once on every change.
  double control_period_s = 0.2;
  /// With no valid telemetry for this long [s], the link is quiet: the bridge sends a stop and holds it until
  /// telemetry is back and a new command is given. 1.5 s is 1.5 periods of the real robot's 1 Hz telemetry.
  double watchdog_s = 1.5;
  /// A command holds for this long [s] unless a new one (or keep_alive()) renews it; then the bridge commands a stop
  /// and keeps sending it until the next command. Whatever drives the bridge (a script, stdin, ROS, a browser
  /// through wmd) must repeat its command faster than this; a driver that hangs or vanishes stops the robot within
  /// this time plus one poll (20 ms). 0: off (a command holds until the next).
  double command_timeout_s = 0.5;
  /// Poses go to the sink once every period [s] (0: only the final one at shutdown).
  double report_period_s = 0.2;
  /// On halt() and shutdown: this many stop packets over this many seconds, so that one survives a lossy link.
  unsigned stop_burst_count = 5;
  double stop_burst_duration_s = 0.2;
  OdometrySource odometry = OdometrySource::automatic;
  /// SI ↔ axes (limits, minimum speed, axes and signs).
  VelocityConverterOptions units;
  /// Track ids, counts per metre, width and the covariance model; also the noise model in commanded mode.
  OdometryOptions tracks;
  /// The odometry's start pose (the robot's pose in the world model's frame when the bridge starts).
  OdometryPose start;
  /// A telemetry step with less travel than these on both counts [m], [rad] is "standing still".
  double still_distance_m = 0.002;
  double still_rotation_rad = 0.01;
  /// Where log lines go (default: stderr, prefixed "wm-servosila: "). Called with the bridge's lock held: it must
  /// not call the bridge. Repeated problems of one kind are logged at most once per log_interval_s.
  std::function<void(const std::string&)> log;
  double log_interval_s = 5.0;
};

/// Counters since start. Telemetry rejections are all "counted, logged (rate-limited) and ignored".
struct BridgeStats {
  std::uint64_t control_sent = 0;           // control packets sent
  std::uint64_t stop_sent = 0;              // of which with both platform axes 0
  std::uint64_t control_send_errors = 0;    // sendto failed
  std::uint64_t commands = 0;               // set_velocity calls
  std::uint64_t commands_rejected = 0;      // NaN or ±∞: a stop
  std::uint64_t commands_clamped = 0;       // beyond the limits
  std::uint64_t commands_raised = 0;        // non-zero below the minimum speed, raised to it
  std::uint64_t commands_ignored = 0;       // after halt()
  std::uint64_t command_timeouts = 0;       // a moving command expired (command_timeout_s): a stop
  std::uint64_t telemetry_received = 0;     // valid telemetry from the robot
  std::uint64_t foreign = 0;                // datagrams from another address (or port) than the robot's
  std::uint64_t truncated = 0;              // shorter than the packet its frame type announces (or empty)
  std::uint64_t oversized = 0;              // longer than that
  std::uint64_t unknown_frame_type = 0;     // first byte not 1, 2 or 4
  std::uint64_t unexpected_frame_type = 0;  // a control packet (type 1) from the robot
  std::uint64_t too_many_motors = 0;        // motor count above 10
  std::uint64_t video_frames = 0;           // type 4: not decoded, skipped (not an error)
  std::uint64_t odometry_advanced = 0;
  std::uint64_t odometry_stale = 0;  // late (reordered) telemetry
  std::uint64_t odometry_track_missing = 0;
  std::uint64_t odometry_jumps = 0;     // a track jumped further than max_step_m: re-referenced
  std::uint64_t odometry_restarts = 0;  // the first packet and every robot restart
  std::uint64_t watchdog_trips = 0;     // the link went quiet
  std::uint64_t poses_published = 0;
  std::uint64_t publish_errors = 0;
};
/// One line "name=value ..." of every counter, for the log at exit.
std::string format_stats(const BridgeStats& stats);

/// What the bridge is doing now.
struct BridgeStatus {
  bool link_up = false;           // valid telemetry within the watchdog time
  bool ever_linked = false;       // some valid telemetry has arrived
  bool watchdog_tripped = false;  // the link went quiet and has not come back
  bool stop_latched = false;      // a watchdog stop is held until the next command (given while the link is up)
  bool command_expired = false;   // no command for command_timeout_s: a stop until the next command
  bool halted = false;            // halt() or shutdown(): stops only, for good
  OdometrySource odometry = OdometrySource::automatic;  // automatic until the first telemetry decides
  AxisCommand sent;                                     // the axes of the last control packet
  Velocity sent_velocity;                               // what they stand for
  PoseReport report;                                    // the pose now, with moving/stopped
};

/// Drives one robot. Owns a UDP socket and two threads: one sends the control packets, receives telemetry and
/// watches the link; the other publishes poses to the sink. Thread-safe.
class Bridge {
 public:
  /// Resolves the robot, binds the socket and starts the threads; sends stops until the link is up.
  /// @throw std::invalid_argument for invalid options (the converter's and the odometry's included);
  ///        std::runtime_error when the robot's host does not resolve or the socket cannot be bound.
  explicit Bridge(BridgeOptions options, std::shared_ptr<PoseSink> sink = nullptr);
  /// shutdown().
  ~Bridge();
  Bridge(const Bridge&) = delete;
  Bridge& operator=(const Bridge&) = delete;

  /// The velocity to drive at from now on [m/s, rad/s, counter-clockwise], sent at once and then five times a
  /// second, converted, clamped and raised to the minimum speed. NaN or ±∞ is a stop and is counted. Only sent
  /// while the link is up; a command given while the link is up releases a watchdog stop. Ignored after halt().
  /// Returns the conversion (what is sent while the link is up).
  ConversionResult set_velocity(double linear_mps, double angular_radps);

  /// Renews the current command's lease (command_timeout_s) without sending anything: for a driver in this process
  /// whose one command holds for a known time (a drive script). Does not undo an expiry that already happened.
  void keep_alive();

  /// Stops for good: from now on every control packet is a stop, and a burst of stop packets is sent at once
  /// (stop_burst_count over stop_burst_duration_s; blocks that long). For signal handlers' threads. Idempotent
  /// except for the burst, which is sent on every call.
  void halt();

  /// halt(), then the reporter stops, the final pose goes to the sink (as "stopped" only if it is confirmed) and
  /// the socket thread ends. Idempotent.
  void shutdown();

  /// Waits until valid telemetry has arrived (the link is up); false on timeout.
  bool wait_for_link(std::chrono::milliseconds timeout);
  /// Waits until the robot is confirmed stopped (see PoseReport::moving); false on timeout.
  bool wait_until_stopped(std::chrono::milliseconds timeout);

  BridgeStatus status() const;
  BridgeStats stats() const;
  /// The bound local UDP port.
  std::uint16_t local_port() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wm::robot
