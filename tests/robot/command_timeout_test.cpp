// The bridge's command timeout against the simulator on loopback, and the "v w" datagram input (ROS, joysticks).
#include <gtest/gtest.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/udp.hpp>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "clients/robot/command_input.h"
#include "clients/robot/remote_drive.h"
#include "clients/robot/servosila_bridge.h"
#include "clients/robot/servosila_sim.h"
#include "tests/robot/servosila_bridge_test_helpers.h"

namespace wm::robot {
namespace {

using namespace bridge_test_helpers;

TEST(CommandTimeoutTest, OneCommandAndSilenceStopsTheSimulatedRobotAfterTheTimeout) {
  ServosilaSim sim(sim_options());
  LogLines log;
  BridgeOptions o = test_options(sim.port(), log);
  o.command_timeout_s = 0.5;
  Bridge bridge(o);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000))) << log.all();

  std::vector<double> latencies_ms;
  for (int trial = 0; trial < 3; ++trial) {
    const Clock::time_point commanded = Clock::now();
    bridge.set_velocity(0.3, 0.0);
    ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(500)));
    ASSERT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(2000))) << "the timeout stopped it";
    const double after_ms = std::chrono::duration<double, std::milli>(Clock::now() - commanded).count();
    EXPECT_GE(after_ms, 480.0) << "it held for the timeout";
    latencies_ms.push_back(after_ms - 500.0);
    EXPECT_TRUE(bridge.status().command_expired);
    std::this_thread::sleep_for(milliseconds(300));
    EXPECT_FALSE(moving(sim)) << "and keeps sending stops";
  }
  EXPECT_EQ(bridge.stats().command_timeouts, 3u);
  EXPECT_FALSE(sim.truth().watchdog_stopped) << "a stop packet stopped it, not the simulator's watchdog";
  double worst = 0.0;
  for (const double l : latencies_ms) worst = std::max(worst, l);
  std::printf("command timeout: the simulator saw the stop at most %.1f ms after the 0.5 s timeout\n", worst);
}

TEST(CommandTimeoutTest, CommandsRepeatedFasterThanTheTimeoutKeepTheRobotMoving) {
  ServosilaSim sim(sim_options());
  LogLines log;
  BridgeOptions o = test_options(sim.port(), log);
  o.command_timeout_s = 0.5;
  Bridge bridge(o);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000))) << log.all();
  for (int i = 0; i < 12; ++i) {
    bridge.set_velocity(0.3, 0.0);
    std::this_thread::sleep_for(milliseconds(100));
    EXPECT_TRUE(i == 0 || moving(sim));
  }
  for (int i = 0; i < 8; ++i) {
    bridge.keep_alive();
    std::this_thread::sleep_for(milliseconds(100));
    EXPECT_TRUE(moving(sim)) << "keep_alive renews the lease";
  }
  EXPECT_EQ(bridge.stats().command_timeouts, 0u);
  bridge.set_velocity(0.0, 0.0);
  EXPECT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(300)));
}

TEST(CommandInputTest, ParsesTwoNumbersAndRefusesEverythingElse) {
  const auto ok = parse_velocity_line("0.3 -0.5\n");
  ASSERT_TRUE(ok);
  EXPECT_DOUBLE_EQ(ok->linear_mps, 0.3);
  EXPECT_DOUBLE_EQ(ok->angular_radps, -0.5);
  EXPECT_TRUE(parse_velocity_line("\t1e3   2\r\n"));
  EXPECT_TRUE(std::isnan(parse_velocity_line("nan 0")->linear_mps)) << "a number: the bridge makes it a stop";
  EXPECT_TRUE(std::isinf(parse_velocity_line("1e999 0")->linear_mps));
  for (const std::string& bad : std::vector<std::string>{"", "\n", "0.3", "0.3 0 0", "0.3,0", "x y", "0.3 0x", "0.3\n0",
                                                         std::string("0.3 0\0", 6), "0.3 0\xff",
                                                         std::string(200, '1') + " 0", "  ", "0.3 0\n\n"}) {
    EXPECT_FALSE(parse_velocity_line(bad)) << "'" << bad << "'";
  }
}

TEST(CommandInputTest, HostileDatagramsBecomeStopsAndHugeValuesAreClampedByTheBridge) {
  ServosilaSim sim(sim_options());
  LogLines log;
  BridgeOptions o = test_options(sim.port(), log);
  o.command_timeout_s = 0.5;
  Bridge bridge(o);
  ASSERT_TRUE(bridge.wait_for_link(milliseconds(2000))) << log.all();
  CommandInput input("127.0.0.1", 0,
                     [&](const VelocityLine& line, bool) { bridge.set_velocity(line.linear_mps, line.angular_radps); });
  asio::io_context io;
  udp::socket socket(io, udp::endpoint(asio::ip::address_v4::loopback(), 0));
  const udp::endpoint to(asio::ip::address_v4::loopback(), input.port());
  const auto send = [&](const std::string& text) { socket.send_to(asio::buffer(text), to); };

  send("1e300 -1e300\n");
  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(500)));
  EXPECT_LE(sim.truth().velocity.linear_mps, o.units.max_linear_mps + 1e-3) << "clamped";
  EXPECT_GE(sim.truth().velocity.angular_radps, -o.units.max_angular_radps - 1e-3);
  send("garbage");
  EXPECT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(1000))) << "garbage is a stop";

  send("0.3 0");
  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(500)));
  send("nan 0");
  EXPECT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(1000))) << "NaN is a stop";

  send("0.3 0");
  ASSERT_TRUE(wait_until([&] { return moving(sim); }, milliseconds(500)));
  send(std::string(5000, '7'));
  EXPECT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(1000))) << "oversized is a stop";

  // A flood, ending on a valid command; the kernel may drop some of it (a full receive buffer), which is fine.
  const auto before = input.stats().received;
  for (int i = 0; i < 2000; ++i) send(i % 2 ? "0.3 0" : "\x01\x02");
  ASSERT_TRUE(wait_until([&] { return input.stats().received >= before + 100; }, milliseconds(2000)));
  ASSERT_TRUE(wait_until([&] { return !moving(sim); }, milliseconds(1500))) << "then the timeout stops it";
  EXPECT_GE(input.stats().refused, 3u);
  EXPECT_GE(bridge.stats().commands_rejected, 1u);
}

// --server as --remote-drive reads it, checked while the flags are parsed and by RemoteDrive itself.
TEST(DriveServerTest, OnlyHttpHostAndPortAreAServer) {
  const auto plain = parse_drive_server("http://localhost:8080");
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->host, "localhost");
  EXPECT_EQ(plain->port, "8080");
  const auto v6 = parse_drive_server("http://[::1]:9/");
  ASSERT_TRUE(v6);
  EXPECT_EQ(v6->host, "::1");
  EXPECT_EQ(v6->port, "9");
  EXPECT_EQ(parse_drive_server("http://wmd")->port, "80");
  for (const std::string bad : {"https://wmd:8080", "http://wmd:8080//", "http://wmd:8080/api", "wmd:8080", "http://",
                                "http://[::1", "http://a b:80", "http://wmd:123456"})
    EXPECT_FALSE(parse_drive_server(bad)) << bad;
}

}  // namespace
}  // namespace wm::robot
