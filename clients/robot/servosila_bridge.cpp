#include "clients/robot/servosila_bridge.h"

#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <thread>
#include <vector>

#include "clients/robot/servosila_bridge_internal.h"
#include "clients/robot/servosila_protocol.h"

namespace wm::robot {
using namespace internal;

namespace {

double unix_now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

bool is_zero(const AxisCommand& axes) { return axes.drive == 0 && axes.turn == 0; }

const MotorRecord* find_motor(const TelemetryPacket& packet, std::uint8_t id) {
  for (const MotorRecord& m : packet.motors) {
    if (m.device_id == id) return &m;
  }
  return nullptr;
}

}  // namespace

struct Bridge::Impl {
  Impl(BridgeOptions o, std::shared_ptr<PoseSink> s)
      : options(std::move(o)),
        sink(std::move(s)),
        converter(options.units),
        odometry(options.tracks, options.start),
        log(options.log ? options.log : default_log(), options.log_interval_s),
        mode(options.odometry) {}

  ~Impl() {
    if (fd >= 0) ::close(fd);
  }

  void open_socket() {
    robot = resolve(options.robot_host, options.robot_port);
    fd = ::socket(robot.address.ss_family, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd < 0) throw std::runtime_error(std::string("socket: ") + std::strerror(errno));
    sockaddr_storage local{};
    socklen_t length = 0;
    if (robot.address.ss_family == AF_INET6) {
      auto& in6 = reinterpret_cast<sockaddr_in6&>(local);
      in6.sin6_family = AF_INET6;
      in6.sin6_addr = in6addr_any;
      in6.sin6_port = htons(options.listen_port);
      length = sizeof in6;
    } else {
      auto& in = reinterpret_cast<sockaddr_in&>(local);
      in.sin_family = AF_INET;
      in.sin_addr.s_addr = htonl(INADDR_ANY);
      in.sin_port = htons(options.listen_port);
      length = sizeof in;
    }
    if (::bind(fd, reinterpret_cast<const sockaddr*>(&local), length) != 0) {
      throw std::runtime_error("cannot bind UDP port " + std::to_string(options.listen_port) + ": " +
                               std::strerror(errno));
    }
    sockaddr_storage bound{};
    socklen_t bound_length = sizeof bound;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &bound_length);
    local_port = bound.ss_family == AF_INET6 ? ntohs(reinterpret_cast<const sockaddr_in6&>(bound).sin6_port)
                                             : ntohs(reinterpret_cast<const sockaddr_in&>(bound).sin_port);
  }

  void start() {
    const Clock::time_point now = Clock::now();
    integrated_until = now;
    io_thread = std::thread([this] { io_loop(); });
    if (sink && options.report_period_s > 0.0) reporter_thread = std::thread([this] { report_loop(); });
  }

  // ---- everything below with `mutex` held, unless it says otherwise ----

  bool link_up_locked(Clock::time_point now) const {
    return last_telemetry && now - *last_telemetry < to_duration(options.watchdog_s);
  }

  AxisCommand effective_locked() const {
    if (halted || stop_latched || command_expired) return AxisCommand{};
    return command.axes;
  }

  /// Commanded odometry: the pose moves with the velocity the last control packet stands for, up to now.
  void integrate_locked(Clock::time_point now) {
    if (mode == OdometrySource::commanded && now > integrated_until) {
      const double dt = std::chrono::duration<double>(now - integrated_until).count();
      if (integrating.linear_mps != 0.0 || integrating.angular_radps != 0.0) {
        odometry.advance(integrating.linear_mps * dt, integrating.angular_radps * dt);
      }
    }
    integrated_until = std::max(integrated_until, now);
  }

  void send_locked(Clock::time_point now) {
    integrate_locked(now);
    const AxisCommand axes = effective_locked();
    ControlPacket packet;  // zero-initialised: every button 0 (button 9 would turn the platform axes into waist)
    converter.write_axes(axes, packet);
    const auto bytes = encode_control(packet);
    const ssize_t n = ::sendto(fd, bytes.data(), bytes.size(), MSG_DONTWAIT,
                               reinterpret_cast<const sockaddr*>(&robot.address), robot.length);
    if (n != static_cast<ssize_t>(bytes.size())) {
      ++stats.control_send_errors;
      log.limited(
          "send",
          std::string("cannot send a control packet to ") + to_string(robot.address) + ": " + std::strerror(errno),
          now);
    } else {
      ++stats.control_sent;
      if (is_zero(axes)) ++stats.stop_sent;
    }
    if (is_zero(axes)) {
      if (!zero_since) zero_since = now;
    } else {
      zero_since.reset();
    }
    sent = axes;
    integrating = converter.to_velocity(axes);
    changed.notify_all();
  }

  void check_watchdog_locked(Clock::time_point now) {
    if (!last_telemetry) {
      if (now - started_at > to_duration(options.watchdog_s)) {
        log.limited("no-link", "no telemetry from the robot at " + to_string(robot.address) + " yet; sending stops",
                    now);
      }
      return;
    }
    if (tripped || link_up_locked(now)) return;
    tripped = true;
    ++stats.watchdog_trips;
    const bool was_moving = !is_zero(effective_locked());
    stop_latched = true;
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%g", options.watchdog_s);
    log.always(std::string("watchdog: no telemetry for ") + seconds +
               " s; sending stops (held until telemetry is back and a new command is given)");
    if (was_moving || !is_zero(sent)) send_locked(now);
  }

  /// A moving command that nobody renewed within command_timeout_s becomes a stop, sent at once.
  void check_command_timeout_locked(Clock::time_point now) {
    if (options.command_timeout_s <= 0.0 || command_expired || is_zero(command.axes)) return;
    if (now - last_command <= to_duration(options.command_timeout_s)) return;
    command_expired = true;
    ++stats.command_timeouts;
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%g", options.command_timeout_s);
    log.limited("command_timeout", std::string("no velocity command for ") + seconds + " s: stop", now);
    send_locked(now);
  }

  bool confirmed_stopped_locked() const {
    if (!is_zero(effective_locked()) || !is_zero(sent) || !zero_since) return false;
    if (mode == OdometrySource::tracks) return still && still_at > *zero_since;
    if (mode == OdometrySource::commanded) return last_telemetry && *last_telemetry > *zero_since;
    return false;
  }

  PoseReport report_locked(Clock::time_point now) {
    integrate_locked(now);
    return PoseReport{odometry.pose(), !confirmed_stopped_locked(), unix_now(), motors, last_telemetry.has_value()};
  }

  void on_datagram(std::span<const std::uint8_t> bytes, const sockaddr_storage& from, Clock::time_point now) {
    if (!same_peer(from, robot.address, !options.accept_any_robot_port)) {
      ++stats.foreign;
      log.limited("foreign",
                  "ignored a " + std::to_string(bytes.size()) + "-byte datagram from " + to_string(from) +
                      ": not the robot (" + to_string(robot.address) +
                      (options.accept_any_robot_port ? ", any port" : "") + ")",
                  now);
      return;
    }
    const std::string what = std::to_string(bytes.size()) + "-byte datagram from the robot";
    FrameType type{};
    try {
      type = frame_type(bytes);
    } catch (const ProtocolError& e) {
      if (e.reason() == ProtocolError::Reason::wrong_size) {
        ++stats.truncated;
        log.limited("truncated", "ignored an empty datagram from the robot", now);
      } else {
        ++stats.unknown_frame_type;
        log.limited("unknown_frame_type", "ignored a " + what + ": unknown frame type " + std::to_string(bytes[0]),
                    now);
      }
      return;
    }
    if (type == FrameType::video_frame) {
      ++stats.video_frames;  // camera frames are another program's business
      return;
    }
    if (type == FrameType::control) {
      ++stats.unexpected_frame_type;
      log.limited("unexpected_frame_type", "ignored a " + what + ": a control packet (frame type 1)", now);
      return;
    }
    TelemetryPacket packet;
    try {
      packet = decode_telemetry(bytes);
    } catch (const ProtocolError& e) {
      if (e.reason() == ProtocolError::Reason::wrong_size) {
        (bytes.size() < kTelemetryPacketSize ? stats.truncated : stats.oversized) += 1;
        log.limited(bytes.size() < kTelemetryPacketSize ? "truncated" : "oversized",
                    "ignored a " + what + ": telemetry is " + std::to_string(kTelemetryPacketSize) + " bytes", now);
      } else if (e.reason() == ProtocolError::Reason::too_many_motors) {
        ++stats.too_many_motors;
        log.limited("too_many_motors", "ignored a " + what + ": " + e.what(), now);
      } else {
        ++stats.unknown_frame_type;
        log.limited("unknown_frame_type", "ignored a " + what + ": " + e.what(), now);
      }
      return;
    }
    on_telemetry(packet, now);
  }

  void on_telemetry(const TelemetryPacket& packet, Clock::time_point now) {
    ++stats.telemetry_received;
    if (!last_telemetry) {
      log.always("link up: telemetry from " + to_string(robot.address) + " (" + std::to_string(packet.motors.size()) +
                 " motor records)");
    } else if (tripped) {
      log.always("link back: telemetry again; holding the stop until the next command");
    }
    last_telemetry = now;
    tripped = false;
    motors = packet.motors;
    if (mode == OdometrySource::automatic) {
      const bool has_tracks = find_motor(packet, options.tracks.left_track_id) != nullptr &&
                              find_motor(packet, options.tracks.right_track_id) != nullptr;
      mode = has_tracks ? OdometrySource::tracks : OdometrySource::commanded;
      integrated_until = now;
      log.always(has_tracks
                     ? "odometry from the track motors (device ids " + std::to_string(options.tracks.left_track_id) +
                           " and " + std::to_string(options.tracks.right_track_id) + ")"
                     : "telemetry has no track motor records (device ids " +
                           std::to_string(options.tracks.left_track_id) + ", " +
                           std::to_string(options.tracks.right_track_id) +
                           "): odometry from the commanded velocity, as the seed reports for the real "
                           "Engineer's chassis");
    }
    if (mode == OdometrySource::tracks) {
      const double distance_before = odometry.distance_travelled_m();
      const double rotation_before = odometry.rotation_turned_rad();
      switch (odometry.update(packet)) {
        case OdometryUpdate::started:
          ++stats.odometry_restarts;
          still = false;
          if (stats.odometry_restarts > 1) log.always("the robot restarted (its tick went back): counts re-referenced");
          break;
        case OdometryUpdate::advanced:
          ++stats.odometry_advanced;
          still = odometry.distance_travelled_m() - distance_before <= options.still_distance_m &&
                  odometry.rotation_turned_rad() - rotation_before <= options.still_rotation_rad;
          if (still) still_at = now;
          break;
        case OdometryUpdate::stale:
          ++stats.odometry_stale;
          break;
        case OdometryUpdate::track_missing:
          ++stats.odometry_track_missing;
          still = false;
          log.limited("track_missing",
                      "telemetry without the track motors' records: the pose cannot move (--odometry commanded?)", now);
          break;
        case OdometryUpdate::jump_rejected:
          ++stats.odometry_jumps;
          still = false;
          log.limited("jump", "a track count jumped further than max_step_m: re-referenced, pose kept", now);
          break;
      }
    }
    changed.notify_all();
  }

  // ---- threads (no lock held on entry) ----

  void io_loop() {
    std::vector<std::uint8_t> buffer(65536);  // any UDP datagram fits whole, so oversized ones are seen as such
    const Clock::duration period = to_duration(options.control_period_s);
    Clock::time_point next_send = Clock::now();
    while (!quit_io.load()) {
      Clock::time_point now = Clock::now();
      {
        const std::lock_guard lock(mutex);
        check_watchdog_locked(now);
        check_command_timeout_locked(now);
        if (now >= next_send) {
          send_locked(now);
          next_send += period;
          if (next_send <= now) next_send = now + period;
        }
      }
      const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(next_send - now);
      pollfd p{fd, POLLIN, 0};
      const int ready = ::poll(&p, 1, static_cast<int>(std::clamp<std::int64_t>(wait.count() + 1, 1, 20)));
      if (ready <= 0 || (p.revents & POLLIN) == 0) continue;
      for (;;) {
        sockaddr_storage from{};
        socklen_t from_length = sizeof from;
        const ssize_t n = ::recvfrom(fd, buffer.data(), buffer.size(), MSG_DONTWAIT, reinterpret_cast<sockaddr*>(&from),
                                     &from_length);
        if (n < 0) break;  // EAGAIN, or an ICMP error (robot unreachable) reported on this socket
        now = Clock::now();
        const std::lock_guard lock(mutex);
        on_datagram(std::span<const std::uint8_t>(buffer.data(), static_cast<std::size_t>(n)), from, now);
      }
    }
  }

  void report_loop() {
    const Clock::duration period = to_duration(options.report_period_s);
    Clock::time_point next = Clock::now() + period;
    for (;;) {
      {
        std::unique_lock lock(reporter_mutex);
        if (reporter_cv.wait_until(lock, next, [this] { return quit_reporter; })) return;
      }
      next += period;
      const Clock::time_point now = Clock::now();
      if (next <= now) next = now + period;
      publish_once();
    }
  }

  /// Publishes the pose now (no lock held on entry; the sink is called without the lock).
  void publish_once() {
    std::optional<PoseReport> report;
    {
      const std::lock_guard lock(mutex);
      if (mode != OdometrySource::automatic && last_telemetry) report = report_locked(Clock::now());
    }
    if (!report) return;
    std::string error;
    try {
      sink->publish(*report);
    } catch (const std::exception& e) {
      error = e.what();
    }
    const std::lock_guard lock(mutex);
    if (error.empty()) {
      ++stats.poses_published;
    } else {
      ++stats.publish_errors;
      log.limited("publish", "cannot publish the pose: " + error, Clock::now());
    }
  }

  void halt() {
    const unsigned count = options.stop_burst_count;
    const Clock::duration gap =
        count > 1 ? to_duration(options.stop_burst_duration_s / (count - 1)) : Clock::duration{};
    {
      const std::lock_guard lock(mutex);
      if (!halted) log.always("halt: sending stops");
      halted = true;
    }
    Clock::time_point at = Clock::now();
    for (unsigned i = 0; i < count; ++i) {
      if (i > 0) {
        at += gap;
        std::this_thread::sleep_until(at);
      }
      const std::lock_guard lock(mutex);
      send_locked(Clock::now());
    }
  }

  void shutdown() {
    const std::lock_guard once(shutdown_mutex);
    if (shut_down) return;
    shut_down = true;
    halt();
    if (reporter_thread.joinable()) {
      {
        const std::lock_guard lock(reporter_mutex);
        quit_reporter = true;
      }
      reporter_cv.notify_all();
      reporter_thread.join();
    }
    if (sink) publish_once();  // the last word: after every periodic report
    quit_io.store(true);
    if (io_thread.joinable()) io_thread.join();
  }

  BridgeOptions options;
  std::shared_ptr<PoseSink> sink;
  int fd = -1;
  Endpoint robot;
  std::uint16_t local_port = 0;
  const Clock::time_point started_at = Clock::now();

  mutable std::mutex mutex;  // guards everything below up to the threads
  std::condition_variable changed;
  VelocityConverter converter;
  DiffDriveOdometry odometry;
  RateLimitedLog log;
  BridgeStats stats;
  OdometrySource mode;
  ConversionResult command;        // the last command given (its axes are sent when nothing holds a stop)
  Clock::time_point last_command;  // when it was given or last renewed (keep_alive)
  bool command_expired = false;    // it was not renewed within command_timeout_s: stops until the next command
  bool stop_latched = true;        // at start, and after a watchdog stop: released by a command while the link is up
  bool halted = false;
  bool tripped = false;
  std::optional<Clock::time_point> last_telemetry;
  AxisCommand sent;
  std::optional<Clock::time_point> zero_since;  // the control packets have been stops since then
  Velocity integrating;                         // what `sent` stands for (commanded odometry)
  Clock::time_point integrated_until;
  std::vector<MotorRecord> motors;  // of the last valid telemetry packet
  bool still = false;               // the last applied telemetry step showed no motion
  Clock::time_point still_at;

  std::atomic<bool> quit_io{false};
  std::thread io_thread;
  std::mutex reporter_mutex;
  std::condition_variable reporter_cv;
  bool quit_reporter = false;
  std::thread reporter_thread;
  std::mutex shutdown_mutex;
  bool shut_down = false;
};

Bridge::Bridge(BridgeOptions options, std::shared_ptr<PoseSink> sink) {
  validate(options);
  impl_ = std::make_unique<Impl>(std::move(options), std::move(sink));
  impl_->open_socket();
  impl_->start();
}

Bridge::~Bridge() { impl_->shutdown(); }

ConversionResult Bridge::set_velocity(double linear_mps, double angular_radps) {
  const std::lock_guard lock(impl_->mutex);
  Impl& s = *impl_;
  const Clock::time_point now = Clock::now();
  ++s.stats.commands;
  if (s.halted) {
    ++s.stats.commands_ignored;
    return ConversionResult{};
  }
  const ConversionResult result = s.converter.convert(linear_mps, angular_radps);
  s.stats.commands_rejected = s.converter.rejected_count();
  s.stats.commands_clamped = s.converter.clamped_count();
  s.stats.commands_raised = s.converter.raised_count();
  if (result.rejected) {
    s.log.limited(
        "nan",
        "non-finite velocity command (" + std::to_string(linear_mps) + ", " + std::to_string(angular_radps) + "): stop",
        now);
  }
  s.command = result;
  s.last_command = now;
  s.command_expired = false;
  if (s.link_up_locked(now)) s.stop_latched = false;
  s.send_locked(now);
  return result;
}

void Bridge::keep_alive() {
  const std::lock_guard lock(impl_->mutex);
  impl_->last_command = Clock::now();
}

void Bridge::halt() { impl_->halt(); }

void Bridge::shutdown() { impl_->shutdown(); }

bool Bridge::wait_for_link(std::chrono::milliseconds timeout) {
  std::unique_lock lock(impl_->mutex);
  return impl_->changed.wait_for(lock, timeout, [this] { return impl_->link_up_locked(Clock::now()); });
}

bool Bridge::wait_until_stopped(std::chrono::milliseconds timeout) {
  std::unique_lock lock(impl_->mutex);
  return impl_->changed.wait_for(lock, timeout, [this] { return impl_->confirmed_stopped_locked(); });
}

BridgeStatus Bridge::status() const {
  const std::lock_guard lock(impl_->mutex);
  Impl& s = *impl_;
  const Clock::time_point now = Clock::now();
  BridgeStatus status;
  status.link_up = s.link_up_locked(now);
  status.ever_linked = s.last_telemetry.has_value();
  status.watchdog_tripped = s.tripped;
  status.stop_latched = s.stop_latched;
  status.command_expired = s.command_expired;
  status.halted = s.halted;
  status.odometry = s.mode;
  status.sent = s.sent;
  status.sent_velocity = s.converter.to_velocity(s.sent);
  status.report = s.report_locked(now);
  return status;
}

BridgeStats Bridge::stats() const {
  const std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

std::uint16_t Bridge::local_port() const { return impl_->local_port; }

}  // namespace wm::robot
