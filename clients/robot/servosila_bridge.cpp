#include "clients/robot/servosila_bridge.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "clients/robot/servosila_protocol.h"
#include "clients/wmctl/http_client.h"

namespace wm::robot {

namespace {

using Clock = std::chrono::steady_clock;

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument("Bridge: " + message);
}

bool positive_finite(double v) { return std::isfinite(v) && v > 0.0; }

Clock::duration to_duration(double seconds) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

double unix_now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

bool is_zero(const AxisCommand& axes) { return axes.drive == 0 && axes.turn == 0; }

/// Logs the first occurrence of each kind of problem, then at most one line per interval, saying how many were
/// left out in between.
class RateLimitedLog {
 public:
  RateLimitedLog(std::function<void(const std::string&)> sink, double interval_s)
      : sink_(std::move(sink)), interval_(to_duration(interval_s)) {}

  void always(const std::string& message) const { sink_(message); }

  void limited(const std::string& kind, const std::string& message, Clock::time_point now) {
    Entry& e = entries_[kind];
    if (e.logged && now - e.last < interval_) {
      ++e.suppressed;
      return;
    }
    std::string line = message;
    if (e.suppressed > 0) line += " (" + std::to_string(e.suppressed) + " more like it not logged)";
    e = Entry{true, now, 0};
    sink_(line);
  }

 private:
  struct Entry {
    bool logged = false;
    Clock::time_point last;
    std::uint64_t suppressed = 0;
  };
  std::function<void(const std::string&)> sink_;
  Clock::duration interval_;
  std::map<std::string, Entry> entries_;
};

struct Endpoint {
  sockaddr_storage address{};
  socklen_t length = 0;
};

Endpoint resolve(const std::string& host, std::uint16_t port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  const int rc = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found);
  if (rc != 0 || found == nullptr) {
    throw std::runtime_error("cannot resolve robot host '" + host + "': " + ::gai_strerror(rc));
  }
  Endpoint e;
  std::memcpy(&e.address, found->ai_addr, found->ai_addrlen);
  e.length = found->ai_addrlen;
  ::freeaddrinfo(found);
  return e;
}

std::string to_string(const sockaddr_storage& a) {
  std::array<char, INET6_ADDRSTRLEN> text{};
  if (a.ss_family == AF_INET) {
    const auto& in = reinterpret_cast<const sockaddr_in&>(a);
    ::inet_ntop(AF_INET, &in.sin_addr, text.data(), text.size());
    return std::string(text.data()) + ":" + std::to_string(ntohs(in.sin_port));
  }
  if (a.ss_family == AF_INET6) {
    const auto& in6 = reinterpret_cast<const sockaddr_in6&>(a);
    ::inet_ntop(AF_INET6, &in6.sin6_addr, text.data(), text.size());
    return "[" + std::string(text.data()) + "]:" + std::to_string(ntohs(in6.sin6_port));
  }
  return "(address family " + std::to_string(a.ss_family) + ")";
}

bool same_peer(const sockaddr_storage& a, const sockaddr_storage& b, bool compare_port) {
  if (a.ss_family != b.ss_family) return false;
  if (a.ss_family == AF_INET) {
    const auto& x = reinterpret_cast<const sockaddr_in&>(a);
    const auto& y = reinterpret_cast<const sockaddr_in&>(b);
    return x.sin_addr.s_addr == y.sin_addr.s_addr && (!compare_port || x.sin_port == y.sin_port);
  }
  if (a.ss_family == AF_INET6) {
    const auto& x = reinterpret_cast<const sockaddr_in6&>(a);
    const auto& y = reinterpret_cast<const sockaddr_in6&>(b);
    return std::memcmp(&x.sin6_addr, &y.sin6_addr, sizeof x.sin6_addr) == 0 &&
           (!compare_port || x.sin6_port == y.sin6_port);
  }
  return false;
}

const MotorRecord* find_motor(const TelemetryPacket& packet, std::uint8_t id) {
  for (const MotorRecord& m : packet.motors) {
    if (m.device_id == id) return &m;
  }
  return nullptr;
}

void validate(const BridgeOptions& o) {
  require(!o.robot_host.empty(), "robot_host must not be empty");
  require(o.robot_port != 0, "robot_port must not be 0");
  require(positive_finite(o.control_period_s) && o.control_period_s <= 1.0,
          "control_period_s must be in (0, 1] (the robot's own watchdog expects packets)");
  require(positive_finite(o.watchdog_s), "watchdog_s must be finite and > 0");
  require(std::isfinite(o.report_period_s) && o.report_period_s >= 0.0, "report_period_s must be finite and >= 0");
  require(o.stop_burst_count >= 1 && o.stop_burst_count <= 100, "stop_burst_count must be in 1..100");
  require(std::isfinite(o.stop_burst_duration_s) && o.stop_burst_duration_s >= 0.0 && o.stop_burst_duration_s <= 5.0,
          "stop_burst_duration_s must be in [0, 5]");
  require(std::isfinite(o.still_distance_m) && o.still_distance_m >= 0.0, "still_distance_m must be >= 0");
  require(std::isfinite(o.still_rotation_rad) && o.still_rotation_rad >= 0.0, "still_rotation_rad must be >= 0");
  require(positive_finite(o.log_interval_s), "log_interval_s must be finite and > 0");
}

std::function<void(const std::string&)> default_log() {
  return [](const std::string& line) { std::fprintf(stderr, "wm-servosila: %s\n", line.c_str()); };
}

}  // namespace

const char* to_string(OdometrySource source) {
  switch (source) {
    case OdometrySource::automatic:
      return "automatic";
    case OdometrySource::tracks:
      return "tracks";
    case OdometrySource::commanded:
      return "commanded";
  }
  return "?";
}

std::string pose_report_json(const PoseReport& report) {
  const OdometryPose& p = report.pose;
  nlohmann::json cov = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) cov.push_back({p.covariance(r, 0), p.covariance(r, 1), p.covariance(r, 2)});
  const nlohmann::json body = {{"x", p.x_m},
                               {"y", p.y_m},
                               {"theta", p.theta_rad},
                               {"cov", std::move(cov)},
                               {"stamp", report.stamp_unix_s},
                               {"state", report.moving ? "moving" : "stopped"}};
  return body.dump();
}

bool valid_robot_id(std::string_view id) {
  if (id.empty() || id.size() > 128) return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == ':' || c == '-';
  });
}

struct HttpPoseSink::Impl {
  client::HttpClient client;
  std::string target;
  std::string token;
};

HttpPoseSink::HttpPoseSink(const std::string& server_url, const std::string& robot_id, const std::string& token,
                           std::chrono::seconds timeout) {
  if (!valid_robot_id(robot_id)) {
    throw std::invalid_argument("robot id '" + robot_id + "': expected 1 to 128 of A-Z a-z 0-9 . _ : -");
  }
  impl_ = std::make_unique<Impl>(
      Impl{client::HttpClient(server_url, timeout), "/api/v1/robots/" + robot_id + "/pose", token});
}

HttpPoseSink::~HttpPoseSink() = default;

void HttpPoseSink::publish(const PoseReport& report) {
  const client::HttpResult r =
      impl_->client.request("PUT", impl_->target, pose_report_json(report), "application/json", impl_->token);
  if (r.status < 200 || r.status > 299) {
    throw std::runtime_error("PUT " + impl_->target + ": HTTP " + std::to_string(r.status) + ": " +
                             r.body.substr(0, 300));
  }
}

HostPort parse_host_port(std::string_view text, std::uint16_t default_port) {
  HostPort result;
  std::string_view port_text;
  if (!text.empty() && text.front() == '[') {
    const std::size_t close = text.find(']');
    if (close == std::string_view::npos) throw std::invalid_argument("'" + std::string(text) + "': missing ']'");
    result.host = std::string(text.substr(1, close - 1));
    const std::string_view rest = text.substr(close + 1);
    if (!rest.empty()) {
      if (rest.front() != ':') throw std::invalid_argument("'" + std::string(text) + "': expected ':' after ']'");
      port_text = rest.substr(1);
      if (port_text.empty()) throw std::invalid_argument("'" + std::string(text) + "': missing port");
    }
  } else {
    const std::size_t colon = text.rfind(':');
    if (colon != std::string_view::npos && text.find(':') != colon) {
      result.host = std::string(text);  // a bare IPv6 address
    } else if (colon != std::string_view::npos) {
      result.host = std::string(text.substr(0, colon));
      port_text = text.substr(colon + 1);
      if (port_text.empty()) throw std::invalid_argument("'" + std::string(text) + "': missing port");
    } else {
      result.host = std::string(text);
    }
  }
  if (result.host.empty()) throw std::invalid_argument("'" + std::string(text) + "': missing host");
  result.port = default_port;
  if (!port_text.empty()) {
    unsigned value = 0;
    const auto [end, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), value);
    if (ec != std::errc() || end != port_text.data() + port_text.size() || value == 0 || value > 65535) {
      throw std::invalid_argument("'" + std::string(text) + "': port must be 1..65535");
    }
    result.port = static_cast<std::uint16_t>(value);
  }
  return result;
}

std::string format_stats(const BridgeStats& s) {
  std::ostringstream out;
  out << "control_sent=" << s.control_sent << " stop_sent=" << s.stop_sent
      << " control_send_errors=" << s.control_send_errors << " commands=" << s.commands
      << " commands_rejected=" << s.commands_rejected << " commands_clamped=" << s.commands_clamped
      << " commands_raised=" << s.commands_raised << " commands_ignored=" << s.commands_ignored
      << " telemetry_received=" << s.telemetry_received << " foreign=" << s.foreign << " truncated=" << s.truncated
      << " oversized=" << s.oversized << " unknown_frame_type=" << s.unknown_frame_type
      << " unexpected_frame_type=" << s.unexpected_frame_type << " too_many_motors=" << s.too_many_motors
      << " video_frames=" << s.video_frames << " odometry_advanced=" << s.odometry_advanced
      << " odometry_stale=" << s.odometry_stale << " odometry_track_missing=" << s.odometry_track_missing
      << " odometry_jumps=" << s.odometry_jumps << " odometry_restarts=" << s.odometry_restarts
      << " watchdog_trips=" << s.watchdog_trips << " poses_published=" << s.poses_published
      << " publish_errors=" << s.publish_errors;
  return out.str();
}

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
    if (halted || stop_latched) return AxisCommand{};
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

  bool confirmed_stopped_locked() const {
    if (!is_zero(effective_locked()) || !is_zero(sent) || !zero_since) return false;
    if (mode == OdometrySource::tracks) return still && still_at > *zero_since;
    if (mode == OdometrySource::commanded) return last_telemetry && *last_telemetry > *zero_since;
    return false;
  }

  PoseReport report_locked(Clock::time_point now) {
    integrate_locked(now);
    return PoseReport{odometry.pose(), !confirmed_stopped_locked(), unix_now()};
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
  ConversionResult command;  // the last command given (its axes are sent when nothing holds a stop)
  bool stop_latched = true;  // at start, and after a watchdog stop: released by a command while the link is up
  bool halted = false;
  bool tripped = false;
  std::optional<Clock::time_point> last_telemetry;
  AxisCommand sent;
  std::optional<Clock::time_point> zero_since;  // the control packets have been stops since then
  Velocity integrating;                         // what `sent` stands for (commanded odometry)
  Clock::time_point integrated_until;
  bool still = false;  // the last applied telemetry step showed no motion
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
  if (s.link_up_locked(now)) s.stop_latched = false;
  s.send_locked(now);
  return result;
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
