// wm-servosila-sim: a simulated Servosila Engineer on UDP, for driving the bridge and the server without a robot.
// Prints its true pose as one JSON object per line so that an end-to-end test can compare it with the server's.

#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <charconv>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "clients/robot/servosila_sim.h"

namespace {

constexpr const char* kUsage =
    "usage: wm-servosila-sim [--bind ADDR] [--port N] [--telemetry-period S] [--watchdog S] [--loss P]\n"
    "                        [--reorder P] [--seed N] [--initial-position N] [--print-period S]\n"
    "  --bind ADDR             numeric address to listen on (default 127.0.0.1)\n"
    "  --port N                UDP port (default 10000, the port the authors' library sends to; 0: any)\n"
    "  --telemetry-period S    seconds between telemetry packets (default 1, the real robot's rate)\n"
    "  --watchdog S            stop after S seconds without a valid control packet (default 0.5)\n"
    "  --loss P                drop each datagram with probability P (default 0)\n"
    "  --reorder P             deliver each datagram after the next one with probability P (default 0)\n"
    "  --seed N                random seed for loss and reordering (default 1)\n"
    "  --initial-position N    both track counters at start (default 0)\n"
    "  --print-period S        seconds between truth lines on stdout (default 0.2; 0: none)\n"
    "Signals: SIGUSR1 raises a motor fault (telemetry: every motor's fault flag, the counter counts it), SIGUSR2\n"
    "clears it.\n";

template <typename T>
T parse_number(std::string_view flag, std::string_view text) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size()) {
    throw std::invalid_argument(std::string(flag) + ": not a number: " + std::string(text));
  }
  return value;
}

struct Arguments {
  wm::robot::SimOptions sim;
  double print_period_s = 0.2;
};

Arguments parse(int argc, char** argv) {
  Arguments args;
  args.sim.port = 10000;
  for (int i = 1; i < argc; ++i) {
    const std::string_view flag = argv[i];
    if (flag == "--help" || flag == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    if (i + 1 >= argc) throw std::invalid_argument(std::string(flag) + ": missing value");
    const std::string_view value = argv[++i];
    if (flag == "--bind") {
      args.sim.bind_address = std::string(value);
    } else if (flag == "--port") {
      args.sim.port = parse_number<std::uint16_t>(flag, value);
    } else if (flag == "--telemetry-period") {
      args.sim.telemetry_period_s = parse_number<double>(flag, value);
    } else if (flag == "--watchdog") {
      args.sim.watchdog_s = parse_number<double>(flag, value);
    } else if (flag == "--loss") {
      args.sim.loss_probability = parse_number<double>(flag, value);
    } else if (flag == "--reorder") {
      args.sim.reorder_probability = parse_number<double>(flag, value);
    } else if (flag == "--seed") {
      args.sim.random_seed = parse_number<std::uint64_t>(flag, value);
    } else if (flag == "--initial-position") {
      args.sim.initial_position = parse_number<std::uint32_t>(flag, value);
    } else if (flag == "--print-period") {
      args.print_period_s = parse_number<double>(flag, value);
      if (!(args.print_period_s >= 0.0)) throw std::invalid_argument("--print-period: must be >= 0");
    } else {
      throw std::invalid_argument("unknown option " + std::string(flag));
    }
  }
  return args;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const Arguments args = parse(argc, argv);
    wm::robot::ServosilaSim sim(args.sim);
    std::printf("wm-servosila-sim: listening on %s port %u\n", args.sim.bind_address.c_str(),
                static_cast<unsigned>(sim.port()));
    std::fflush(stdout);

    boost::asio::io_context io;
    boost::asio::signal_set signals(io, SIGINT, SIGTERM);
    signals.async_wait([&io](const boost::system::error_code&, int) { io.stop(); });
    boost::asio::signal_set fault_signals(io, SIGUSR1, SIGUSR2);
    std::function<void()> fault_loop = [&] {
      fault_signals.async_wait([&](const boost::system::error_code& ec, int signal) {
        if (ec) return;
        sim.set_fault(signal == SIGUSR1);
        std::printf("wm-servosila-sim: motor fault %s\n", signal == SIGUSR1 ? "raised" : "cleared");
        std::fflush(stdout);
        fault_loop();
      });
    };
    fault_loop();

    const auto start = std::chrono::steady_clock::now();
    boost::asio::steady_timer timer(io);
    std::function<void()> print_loop = [&] {
      timer.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(args.print_period_s)));
      timer.async_wait([&](const boost::system::error_code& ec) {
        if (ec) return;
        const wm::robot::SimTruth t = sim.truth();
        const double t_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        std::printf(
            "{\"t_s\":%.3f,\"x_m\":%.6f,\"y_m\":%.6f,\"theta_rad\":%.6f,\"linear_mps\":%.6f,"
            "\"angular_radps\":%.6f,\"watchdog_stopped\":%s}\n",
            t_s, t.x_m, t.y_m, t.theta_rad, t.velocity.linear_mps, t.velocity.angular_radps,
            t.watchdog_stopped ? "true" : "false");
        std::fflush(stdout);
        print_loop();
      });
    };
    if (args.print_period_s > 0.0) print_loop();
    io.run();
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "wm-servosila-sim: %s\n%s", e.what(), kUsage);
    return 2;
  }
}
