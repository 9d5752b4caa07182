// wm-servosila: drives a Servosila Engineer (or wm-servosila-sim) over its UDP protocol and reports its odometry
// to wmd as the robot's pose (PUT /api/v1/robots/{id}/pose). Commands come from a --drive script or from stdin
// lines "v w" (m/s rad/s). Stops are sent at exit, on SIGINT/SIGTERM/SIGHUP and when the robot goes quiet
// (clients/robot/PROTOCOL.md, "Running the bridge").

#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "clients/robot/command_input.h"
#include "clients/robot/drive_script.h"
#include "clients/robot/remote_drive.h"
#include "clients/robot/servosila_bridge.h"

namespace {

using wm::robot::Bridge;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

constexpr const char* kUsage =
    "usage: wm-servosila --robot HOST[:PORT] [--server URL] [--id NAME] [options] [--drive SCRIPT]\n"
    "Drives a Servosila Engineer over UDP and reports its odometry to wmd as the robot's pose.\n"
    "  --robot HOST[:PORT]   the robot (or wm-servosila-sim); port default 10000 (the authors' library)\n"
    "  --listen PORT         local UDP port for control and telemetry (default 0: any)\n"
    "  --robot-any-port      accept telemetry from the robot's address on any port (default: its port only)\n"
    "  --server URL          wmd, e.g. http://127.0.0.1:8080 (default: none, poses are not reported)\n"
    "  --token T             bearer token for wmd (when it runs with --token)\n"
    "  --id NAME             robot id in wmd (default servosila; A-Z a-z 0-9 . _ : -)\n"
    "  --rate HZ             pose reports per second (default 5; 0: only the final one)\n"
    "  --watchdog S          stop when no telemetry came for S seconds (default 1.5)\n"
    "  --max-speed M/S       linear limit (default 0.4; 0.2 to 0.455, the int16 axis range)\n"
    "  --max-turn RAD/S      angular limit (default 1.25; 0.2 to 1.365)\n"
    "  --odometry MODE       tracks | commanded | auto (default auto: tracks when telemetry has the track\n"
    "                        motors, else the commanded velocity, as on the real Engineer)\n"
    "  --start X,Y,THETA     the robot's pose in the world model's frame at start (default 0,0,0)\n"
    "  --drive SCRIPT        e.g. \"F 2; L 90; F 2; L 90\": F/B metres forward/back, L/R degrees left/right,\n"
    "                        W seconds standing; without --drive, stdin lines \"v w\" (m/s rad/s) until EOF\n"
    "  --speed M/S           scripted linear speed (default 0.3; at least 0.2, the robot's minimum)\n"
    "  --turn-speed RAD/S    scripted turn speed (default 0.6; at least 0.2)\n"
    "  --pause S             standstill between two scripted moves (default 0.5)\n"
    "  --link-timeout S      give up when no telemetry came within S seconds of start (default 10)\n"
    "  --command-timeout S   stop when no new command came for S seconds, whatever sends them (default 0.5;\n"
    "                        0: a command holds until the next)\n"
    "  --remote-drive        take drivers' commands from wmd (--server): a WebSocket to\n"
    "                        /api/v1/robots/ID/drive?role=robot; the web viewer's drive panel drives the robot\n"
    "  --remote-hold S       stop when wmd relayed no command for S seconds while moving (default 0.3)\n"
    "  --command-udp [ADDR:]PORT  also take \"v w\" commands as UDP datagrams (default address 127.0.0.1);\n"
    "                        without --drive, stdin is then not read and the bridge runs until a signal\n"
    "Exit: 0 when the drive ended and the robot was seen stopped; 1 on a lost link or an unconfirmed stop;\n"
    "2 on bad flags; 128+N after signal N. A stop is sent in every case.\n";

double parse_double(std::string_view flag, std::string_view text) {
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
    throw std::invalid_argument(std::string(flag) + ": not a finite number: '" + std::string(text) + "'");
  }
  return value;
}

double parse_positive(std::string_view flag, std::string_view text) {
  const double v = parse_double(flag, text);
  if (!(v > 0.0)) throw std::invalid_argument(std::string(flag) + ": must be > 0");
  return v;
}

struct Arguments {
  wm::robot::BridgeOptions bridge;
  std::string server;
  std::string token;
  std::string id = "servosila";
  std::optional<std::string> drive;
  double speed_mps = 0.3;
  double turn_speed_radps = 0.6;
  double pause_s = 0.5;
  double link_timeout_s = 10.0;
  std::optional<wm::robot::HostPort> command_udp;
  bool remote_drive = false;
  double remote_hold_s = 0.3;
};

Arguments parse(int argc, char** argv) {
  Arguments args;
  bool have_robot = false;
  for (int i = 1; i < argc; ++i) {
    const std::string_view flag = argv[i];
    if (flag == "--help" || flag == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    if (flag == "--robot-any-port") {
      args.bridge.accept_any_robot_port = true;
      continue;
    }
    if (flag == "--remote-drive") {
      args.remote_drive = true;
      continue;
    }
    if (i + 1 >= argc) throw std::invalid_argument(std::string(flag) + ": missing value");
    const std::string_view value = argv[++i];
    if (flag == "--robot") {
      const wm::robot::HostPort robot = wm::robot::parse_host_port(value, 10000);
      args.bridge.robot_host = robot.host;
      args.bridge.robot_port = robot.port;
      have_robot = true;
    } else if (flag == "--listen") {
      const double port = parse_double(flag, value);
      if (port < 0 || port > 65535 || port != std::floor(port)) throw std::invalid_argument("--listen: 0..65535");
      args.bridge.listen_port = static_cast<std::uint16_t>(port);
    } else if (flag == "--server") {
      args.server = std::string(value);
    } else if (flag == "--token") {
      args.token = std::string(value);
    } else if (flag == "--id") {
      args.id = std::string(value);
      if (!wm::robot::valid_robot_id(args.id)) {
        throw std::invalid_argument("--id: 1 to 128 of A-Z a-z 0-9 . _ : -");
      }
    } else if (flag == "--rate") {
      const double rate = parse_double(flag, value);
      if (rate < 0.0 || rate > 100.0) throw std::invalid_argument("--rate: must be in [0, 100]");
      args.bridge.report_period_s = rate > 0.0 ? 1.0 / rate : 0.0;
    } else if (flag == "--watchdog") {
      args.bridge.watchdog_s = parse_positive(flag, value);
    } else if (flag == "--max-speed") {
      args.bridge.units.max_linear_mps = parse_positive(flag, value);
      if (args.bridge.units.max_linear_mps < wm::robot::kMinimumLinearMps || args.bridge.units.max_linear_mps > 0.455) {
        throw std::invalid_argument(
            "--max-speed: must be in [0.2, 0.455] m/s (the robot's minimum speed, the axis range)");
      }
    } else if (flag == "--max-turn") {
      args.bridge.units.max_angular_radps = parse_positive(flag, value);
      if (args.bridge.units.max_angular_radps < wm::robot::kMinimumAngularRadps ||
          args.bridge.units.max_angular_radps > 1.365) {
        throw std::invalid_argument("--max-turn: must be in [0.2, 1.365] rad/s (the robot's minimum, the axis range)");
      }
    } else if (flag == "--odometry") {
      if (value == "tracks") {
        args.bridge.odometry = wm::robot::OdometrySource::tracks;
      } else if (value == "commanded") {
        args.bridge.odometry = wm::robot::OdometrySource::commanded;
      } else if (value == "auto") {
        args.bridge.odometry = wm::robot::OdometrySource::automatic;
      } else {
        throw std::invalid_argument("--odometry: expected tracks, commanded or auto");
      }
    } else if (flag == "--start") {
      const std::string text(value);
      const std::size_t a = text.find(',');
      const std::size_t b = a == std::string::npos ? a : text.find(',', a + 1);
      if (b == std::string::npos) throw std::invalid_argument("--start: expected X,Y,THETA");
      args.bridge.start.x_m = parse_double(flag, std::string_view(text).substr(0, a));
      args.bridge.start.y_m = parse_double(flag, std::string_view(text).substr(a + 1, b - a - 1));
      args.bridge.start.theta_rad = parse_double(flag, std::string_view(text).substr(b + 1));
    } else if (flag == "--drive") {
      args.drive = std::string(value);
    } else if (flag == "--speed") {
      args.speed_mps = parse_positive(flag, value);
    } else if (flag == "--turn-speed") {
      args.turn_speed_radps = parse_positive(flag, value);
    } else if (flag == "--pause") {
      args.pause_s = parse_double(flag, value);
      if (args.pause_s < 0.0) throw std::invalid_argument("--pause: must be >= 0");
    } else if (flag == "--link-timeout") {
      args.link_timeout_s = parse_positive(flag, value);
    } else if (flag == "--command-timeout") {
      args.bridge.command_timeout_s = parse_double(flag, value);
      if (args.bridge.command_timeout_s < 0.0 || args.bridge.command_timeout_s > 3600.0)
        throw std::invalid_argument("--command-timeout: must be in [0, 3600] s");
    } else if (flag == "--remote-hold") {
      args.remote_hold_s = parse_positive(flag, value);
      if (args.remote_hold_s > 3600.0) throw std::invalid_argument("--remote-hold: must be in (0, 3600] s");
    } else if (flag == "--command-udp") {
      const std::string text(value);
      args.command_udp = text.find(':') == std::string::npos ? wm::robot::parse_host_port("127.0.0.1:" + text, 0)
                                                             : wm::robot::parse_host_port(text, 0);
    } else {
      throw std::invalid_argument("unknown option " + std::string(flag));
    }
  }
  if (!have_robot) throw std::invalid_argument("--robot HOST[:PORT] is required");
  if (args.remote_drive && args.server.empty()) throw std::invalid_argument("--remote-drive needs --server");
  // The URL RemoteDrive accepts (its constructor throws otherwise, after the bridge's threads have started).
  if (args.remote_drive && !wm::robot::parse_drive_server(args.server))
    throw std::invalid_argument("--remote-drive: --server must be http://host[:port] (got '" + args.server + "')");
  return args;
}

/// The signal that asked us to stop (0: none yet), for the main thread to wait on.
class Interrupt {
 public:
  void raise(int signal) {
    {
      const std::lock_guard lock(mutex_);
      signal_ = signal;
    }
    cv_.notify_all();
  }
  int signal() const {
    const std::lock_guard lock(mutex_);
    return signal_;
  }
  /// Sleeps until `t` or a signal; true when interrupted.
  bool sleep_until(Clock::time_point t) {
    std::unique_lock lock(mutex_);
    return cv_.wait_until(lock, t, [this] { return signal_ != 0; });
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  int signal_ = 0;
};

void log(const std::string& line) { std::fprintf(stderr, "wm-servosila: %s\n", line.c_str()); }

std::string fixed(double v, int digits = 3) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, v);
  return buffer;
}

enum class Outcome { done, link_lost, interrupted };

/// Waits for the link, checking for a signal; true when it is up.
bool wait_for_link(Bridge& bridge, Interrupt& interrupt, double timeout_s) {
  const Clock::time_point deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  while (Clock::now() < deadline) {
    if (interrupt.signal() != 0) return false;
    if (bridge.wait_for_link(milliseconds(50))) return true;
  }
  return false;
}

/// The link went quiet during a drive: the bridge has stopped the robot and holds the stop.
bool link_lost(const Bridge& bridge) { return bridge.status().watchdog_tripped; }

Outcome run_script(Bridge& bridge, Interrupt& interrupt, const std::vector<wm::robot::DriveSegment>& segments) {
  Clock::time_point at = Clock::now();
  std::size_t index = 0;
  for (const auto& segment : segments) {
    ++index;
    if (link_lost(bridge)) return Outcome::link_lost;
    log("step " + std::to_string(index) + "/" + std::to_string(segments.size()) + ": v " + fixed(segment.linear_mps) +
        " m/s, w " + fixed(segment.angular_radps) + " rad/s for " + fixed(segment.duration_s) + " s");
    bridge.set_velocity(segment.linear_mps, segment.angular_radps);
    at += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(segment.duration_s));
    while (Clock::now() < at) {
      if (interrupt.sleep_until(std::min(at, Clock::now() + milliseconds(50)))) return Outcome::interrupted;
      if (link_lost(bridge)) return Outcome::link_lost;
      bridge.keep_alive();  // the script is the driver: its step holds for its time, not for the command timeout
    }
  }
  bridge.set_velocity(0.0, 0.0);
  return Outcome::done;
}

/// Reads "v w" lines from stdin until EOF. A line that is not two numbers is a stop (and logged). Each line holds
/// for the bridge's command timeout.
Outcome run_stdin(Bridge& bridge, Interrupt& interrupt) {
  std::string pending;
  char buffer[4096];
  for (;;) {
    if (interrupt.signal() != 0) return Outcome::interrupted;
    pollfd p{STDIN_FILENO, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof buffer);
    if (n <= 0) break;  // EOF (or an error): the end of the commands
    pending.append(buffer, static_cast<std::size_t>(n));
    for (std::size_t eol = pending.find('\n'); eol != std::string::npos; eol = pending.find('\n')) {
      std::string line = pending.substr(0, eol);
      pending.erase(0, eol + 1);
      if (const auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
      const auto first = line.find_first_not_of(" \t\r");
      if (first == std::string::npos) continue;
      double v = 0.0;
      double w = 0.0;
      char extra = 0;
      // %lf accepts "nan" and "inf": the bridge turns those into a stop and counts them.
      if (std::sscanf(line.c_str(), "%lf %lf %c", &v, &w, &extra) != 2) {
        log("not \"v w\": '" + line + "': stop");
        v = 0.0;
        w = 0.0;
      }
      bridge.set_velocity(v, w);
    }
  }
  bridge.set_velocity(0.0, 0.0);
  return Outcome::done;
}

/// Commands come from elsewhere (--command-udp): serves them until a signal.
Outcome run_until_signal(Interrupt& interrupt) {
  while (!interrupt.sleep_until(Clock::now() + milliseconds(500))) {
  }
  return Outcome::interrupted;
}

/// Waits until the bridge sees the robot stopped, or a signal, or the timeout.
bool settle(Bridge& bridge, Interrupt& interrupt, double timeout_s, bool stop_on_signal) {
  const Clock::time_point deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  while (Clock::now() < deadline) {
    if (stop_on_signal && interrupt.signal() != 0) return false;
    if (bridge.wait_until_stopped(milliseconds(50))) return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  Arguments args;
  std::vector<wm::robot::DriveSegment> segments;
  std::shared_ptr<wm::robot::PoseSink> sink;
  try {
    args = parse(argc, argv);
    if (args.drive) {
      // The script's durations use the speeds the robot really gets: after the limits and the minimum speed.
      wm::robot::VelocityConverter converter(args.bridge.units);
      const double v = std::abs(converter.convert(args.speed_mps, 0.0).sent.linear_mps);
      const double w = std::abs(converter.convert(0.0, args.turn_speed_radps).sent.angular_radps);
      if (std::abs(v - args.speed_mps) > 0.005 || std::abs(w - args.turn_speed_radps) > 0.005) {
        log("scripted speeds as the robot gets them: " + fixed(v) + " m/s, " + fixed(w) + " rad/s");
      }
      segments = wm::robot::plan_drive(wm::robot::parse_drive_script(*args.drive), v, w, args.pause_s);
      // Command the speeds as given (within the limits and above the minimum), not their rounded axis values, so
      // that they do not count as clamped.
      const auto& u = args.bridge.units;
      const double v_command = std::clamp(args.speed_mps, u.min_linear_mps, u.max_linear_mps);
      const double w_command = std::clamp(args.turn_speed_radps, u.min_angular_radps, u.max_angular_radps);
      for (auto& segment : segments) {
        if (segment.linear_mps != 0.0) segment.linear_mps = std::copysign(v_command, segment.linear_mps);
        if (segment.angular_radps != 0.0) segment.angular_radps = std::copysign(w_command, segment.angular_radps);
      }
    }
    if (!args.server.empty()) sink = std::make_shared<wm::robot::HttpPoseSink>(args.server, args.id, args.token);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "wm-servosila: %s\n%s", e.what(), kUsage);
    return 2;
  }

  // Signals go to one thread that waits for them (sigwait), so that a stop burst never runs in a signal handler.
  // They must be blocked before any thread starts, the bridge's included.
  sigset_t signals;
  sigemptyset(&signals);
  for (const int s : {SIGINT, SIGTERM, SIGHUP, SIGUSR1}) sigaddset(&signals, s);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  ::signal(SIGPIPE, SIG_IGN);

  std::unique_ptr<Bridge> bridge;
  try {
    bridge = std::make_unique<Bridge>(args.bridge, sink);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "wm-servosila: %s\n%s", e.what(), kUsage);
    return 2;
  } catch (const std::exception& e) {
    log(e.what());
    return 1;
  }
  log("robot " + args.bridge.robot_host + ":" + std::to_string(args.bridge.robot_port) + " from UDP port " +
      std::to_string(bridge->local_port()) +
      (args.server.empty() ? std::string("; no --server: poses are not reported")
                           : "; poses to " + args.server + " as robot '" + args.id + "'"));

  Interrupt interrupt;
  std::thread signal_thread([&] {
    for (;;) {
      int received = 0;
      if (sigwait(&signals, &received) != 0) continue;
      if (received == SIGUSR1) return;  // main is done
      log(std::string("signal ") + std::to_string(received) + ": stopping the robot");
      bridge->halt();  // the stop burst at once, whatever the main thread is doing
      interrupt.raise(received);
      return;
    }
  });

  std::unique_ptr<wm::robot::CommandInput> command_input;
  if (args.command_udp) {
    try {
      command_input = std::make_unique<wm::robot::CommandInput>(
          args.command_udp->host, args.command_udp->port, [&bridge](const wm::robot::VelocityLine& line, bool refused) {
            if (refused) log("a command datagram that is not \"v w\": stop");
            bridge->set_velocity(line.linear_mps, line.angular_radps);
          });
      log("commands: \"v w\" datagrams on UDP " + args.command_udp->host + ":" + std::to_string(command_input->port()));
    } catch (const std::exception& e) {
      log(e.what());
      bridge->shutdown();
      pthread_kill(signal_thread.native_handle(), SIGUSR1);
      signal_thread.join();
      return 1;
    }
  }

  std::unique_ptr<wm::robot::RemoteDrive> remote_drive;
  if (args.remote_drive) {
    wm::robot::RemoteDriveOptions remote;
    remote.server_url = args.server;
    remote.robot_id = args.id;
    remote.token = args.token;
    remote.hold_s = args.remote_hold_s;
    remote_drive =
        std::make_unique<wm::robot::RemoteDrive>(remote, [&bridge](double v, double w) { bridge->set_velocity(v, w); });
  }

  int code = 0;
  bool stopped = false;
  if (!wait_for_link(*bridge, interrupt, args.link_timeout_s)) {
    if (interrupt.signal() == 0) {
      log("no telemetry from the robot within " + fixed(args.link_timeout_s, 1) + " s (is it on, is --robot right?)");
      code = 1;
    }
  } else {
    const Outcome outcome = args.drive ? run_script(*bridge, interrupt, segments)
                            : command_input != nullptr || remote_drive != nullptr ? run_until_signal(interrupt)
                                                                                  : run_stdin(*bridge, interrupt);
    if (outcome == Outcome::link_lost) {
      log("link lost during the drive: the robot was sent stops; drive aborted");
      code = 1;
    }
    // A real robot stops within a telemetry period or two; confirming it takes a packet after the stop.
    const double settle_s = outcome == Outcome::interrupted ? 1.0 : 2.0 * args.bridge.watchdog_s + 1.0;
    if (outcome != Outcome::link_lost) {
      stopped = settle(*bridge, interrupt, settle_s, outcome != Outcome::interrupted);
      if (!stopped && outcome == Outcome::done) {
        log("could not confirm that the robot stopped (stops were sent)");
        code = 1;
      }
    }
  }
  command_input.reset();  // no command after this point
  remote_drive.reset();
  bridge->shutdown();  // the stop burst, the final pose, the socket closed

  if (interrupt.signal() == 0) {
    pthread_kill(signal_thread.native_handle(), SIGUSR1);
  }
  signal_thread.join();
  if (interrupt.signal() != 0) code = 128 + interrupt.signal();

  const wm::robot::BridgeStatus status = bridge->status();
  const auto& pose = status.report.pose;
  std::printf(
      "{\"x\":%.9g,\"y\":%.9g,\"theta\":%.9g,\"cov\":[[%.9g,%.9g,%.9g],[%.9g,%.9g,%.9g],[%.9g,%.9g,%.9g]],"
      "\"state\":\"%s\",\"odometry\":\"%s\"}\n",
      pose.x_m, pose.y_m, pose.theta_rad, pose.covariance(0, 0), pose.covariance(0, 1), pose.covariance(0, 2),
      pose.covariance(1, 0), pose.covariance(1, 1), pose.covariance(1, 2), pose.covariance(2, 0), pose.covariance(2, 1),
      pose.covariance(2, 2), status.report.moving ? "moving" : "stopped", wm::robot::to_string(status.odometry));
  std::fflush(stdout);
  log("final pose x " + fixed(pose.x_m) + " m, y " + fixed(pose.y_m) + " m, theta " + fixed(pose.theta_rad) +
      " rad (sigma " + fixed(std::sqrt(pose.covariance(0, 0))) + " m, " + fixed(std::sqrt(pose.covariance(1, 1))) +
      " m, " + fixed(std::sqrt(pose.covariance(2, 2))) + " rad), " + (status.report.moving ? "moving" : "stopped") +
      ", odometry " + wm::robot::to_string(status.odometry));
  log("counters: " + wm::robot::format_stats(bridge->stats()));
  return code;
}
