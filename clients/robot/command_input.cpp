#include "clients/robot/command_input.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace wm::robot {
namespace {

bool is_blank(char c) { return c == ' ' || c == '\t'; }

/// One number: what strtod reads, whole (so "nan", "inf", "1e3" are numbers, "1x" is not).
std::optional<double> parse_number(std::string_view token) {
  if (token.empty() || token.size() > 64) return std::nullopt;
  const std::string text(token);
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) return std::nullopt;
  return v;  // ERANGE overflow gives ±HUGE_VAL (∞): the bridge stops on it
}

}  // namespace

std::optional<VelocityLine> parse_velocity_line(std::string_view text) {
  if (text.size() > kMaxCommandBytes) return std::nullopt;
  if (text.ends_with('\n')) text.remove_suffix(1);
  if (text.ends_with('\r')) text.remove_suffix(1);
  for (const char c : text) {
    if (static_cast<unsigned char>(c) < 0x20 && c != '\t') return std::nullopt;  // NUL, new lines inside, controls
    if (static_cast<unsigned char>(c) >= 0x7f) return std::nullopt;
  }
  std::array<std::string_view, 2> tokens;
  std::size_t count = 0;
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && is_blank(text[i])) ++i;
    if (i == text.size()) break;
    const std::size_t start = i;
    while (i < text.size() && !is_blank(text[i])) ++i;
    if (count == tokens.size()) return std::nullopt;
    tokens[count++] = text.substr(start, i - start);
  }
  if (count != 2) return std::nullopt;
  const auto v = parse_number(tokens[0]);
  const auto w = parse_number(tokens[1]);
  if (!v || !w) return std::nullopt;
  return VelocityLine{*v, *w};
}

struct CommandInput::Impl {
  int fd = -1;
  std::uint16_t port = 0;
  std::function<void(const VelocityLine&, bool)> apply;
  std::atomic<bool> quit{false};
  mutable std::mutex mutex;
  CommandInputStats stats;
  std::thread thread;

  void run() {
    std::array<char, 2048> buffer{};
    while (!quit.load()) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const ssize_t n = ::recv(fd, buffer.data(), buffer.size(), MSG_DONTWAIT | MSG_TRUNC);
      if (n < 0) continue;
      const auto size = static_cast<std::size_t>(n);
      const auto line =
          size > buffer.size() ? std::nullopt : parse_velocity_line(std::string_view(buffer.data(), size));
      {
        const std::lock_guard lock(mutex);
        ++stats.received;
        ++(line ? stats.accepted : stats.refused);
      }
      apply(line.value_or(VelocityLine{}), !line);
    }
  }
};

CommandInput::CommandInput(const std::string& bind_address, std::uint16_t port,
                           std::function<void(const VelocityLine&, bool refused)> apply)
    : impl_(std::make_unique<Impl>()) {
  impl_->apply = std::move(apply);
  sockaddr_storage local{};
  socklen_t length = 0;
  auto& in = reinterpret_cast<sockaddr_in&>(local);
  auto& in6 = reinterpret_cast<sockaddr_in6&>(local);
  if (::inet_pton(AF_INET, bind_address.c_str(), &in.sin_addr) == 1) {
    in.sin_family = AF_INET;
    in.sin_port = htons(port);
    length = sizeof in;
  } else if (::inet_pton(AF_INET6, bind_address.c_str(), &in6.sin6_addr) == 1) {
    in6.sin6_family = AF_INET6;
    in6.sin6_port = htons(port);
    length = sizeof in6;
  } else {
    throw std::runtime_error("command input: '" + bind_address + "' is not a numeric address");
  }
  impl_->fd = ::socket(local.ss_family, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (impl_->fd < 0) throw std::runtime_error(std::string("command input: socket: ") + std::strerror(errno));
  if (::bind(impl_->fd, reinterpret_cast<const sockaddr*>(&local), length) != 0) {
    const std::string reason = std::strerror(errno);
    ::close(impl_->fd);
    throw std::runtime_error("command input: cannot bind UDP " + bind_address + ":" + std::to_string(port) + ": " +
                             reason);
  }
  sockaddr_storage bound{};
  socklen_t bound_length = sizeof bound;
  ::getsockname(impl_->fd, reinterpret_cast<sockaddr*>(&bound), &bound_length);
  impl_->port = bound.ss_family == AF_INET6 ? ntohs(reinterpret_cast<const sockaddr_in6&>(bound).sin6_port)
                                            : ntohs(reinterpret_cast<const sockaddr_in&>(bound).sin_port);
  impl_->thread = std::thread([impl = impl_.get()] { impl->run(); });
}

CommandInput::~CommandInput() {
  impl_->quit.store(true);
  impl_->thread.join();
  ::close(impl_->fd);
}

std::uint16_t CommandInput::port() const { return impl_->port; }

CommandInputStats CommandInput::stats() const {
  const std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

}  // namespace wm::robot
