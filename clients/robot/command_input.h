#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

// Velocity commands from another process on this machine (the ROS cmd_vel forwarder, a joystick program): one UDP
// datagram per command, the text "v w" (m/s, rad/s counter-clockwise), optionally ending in a new line. The bridge
// applies each one as it applies a stdin line; its command timeout stops the robot when they stop coming.

namespace wm::robot {

/// What a command line says.
struct VelocityLine {
  double linear_mps = 0.0;
  double angular_radps = 0.0;
};

/// Parses "v w" (two numbers separated by spaces or tabs, an optional trailing "\n" or "\r\n"). NaN and ±∞ are
/// numbers here: the bridge turns them into a stop and counts them. nullopt for anything else: empty, one number or
/// three, letters, a NUL byte, text over kMaxCommandBytes.
std::optional<VelocityLine> parse_velocity_line(std::string_view text);

/// The longest command datagram accepted [bytes]; longer ones are refused whole.
inline constexpr std::size_t kMaxCommandBytes = 128;

struct CommandInputStats {
  std::uint64_t received = 0;  // datagrams
  std::uint64_t accepted = 0;  // parsed as "v w"
  std::uint64_t refused = 0;   // not "v w" or over kMaxCommandBytes: handed on as a stop
};

/// Listens on a UDP port and hands each datagram's command to `apply` from its own thread. A datagram that is not
/// "v w" is handed on as a stop (0, 0), as a bad stdin line is: a driver that sends garbage meant something, and the
/// safe reading of it is "stop". No authentication: bind it to loopback (the default) unless the network is trusted.
class CommandInput {
 public:
  /// @throw std::runtime_error when the address is not numeric or the port cannot be bound.
  CommandInput(const std::string& bind_address, std::uint16_t port,
               std::function<void(const VelocityLine&, bool refused)> apply);
  ~CommandInput();
  CommandInput(const CommandInput&) = delete;
  CommandInput& operator=(const CommandInput&) = delete;

  std::uint16_t port() const;
  CommandInputStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wm::robot
