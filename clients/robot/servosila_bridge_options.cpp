#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <string>

#include "clients/robot/servosila_bridge.h"
#include "clients/robot/servosila_bridge_internal.h"

// The bridge's options checked and parsed, and its values as text.
namespace wm::robot {
namespace internal {
namespace {

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument("Bridge: " + message);
}

bool positive_finite(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

void validate(const BridgeOptions& o) {
  require(!o.robot_host.empty(), "robot_host must not be empty");
  require(o.robot_port != 0, "robot_port must not be 0");
  require(positive_finite(o.control_period_s) && o.control_period_s <= 1.0,
          "control_period_s must be in (0, 1] (the robot's own watchdog expects packets)");
  require(positive_finite(o.watchdog_s), "watchdog_s must be finite and > 0");
  require(std::isfinite(o.command_timeout_s) && o.command_timeout_s >= 0.0 && o.command_timeout_s <= 3600.0,
          "command_timeout_s must be in [0, 3600] s");
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

}  // namespace internal

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
      << " command_timeouts=" << s.command_timeouts << " telemetry_received=" << s.telemetry_received
      << " foreign=" << s.foreign << " truncated=" << s.truncated << " oversized=" << s.oversized
      << " unknown_frame_type=" << s.unknown_frame_type << " unexpected_frame_type=" << s.unexpected_frame_type
      << " too_many_motors=" << s.too_many_motors << " video_frames=" << s.video_frames
      << " odometry_advanced=" << s.odometry_advanced << " odometry_stale=" << s.odometry_stale
      << " odometry_track_missing=" << s.odometry_track_missing << " odometry_jumps=" << s.odometry_jumps
      << " odometry_restarts=" << s.odometry_restarts << " watchdog_trips=" << s.watchdog_trips
      << " poses_published=" << s.poses_published << " publish_errors=" << s.publish_errors;
  return out.str();
}

}  // namespace wm::robot
