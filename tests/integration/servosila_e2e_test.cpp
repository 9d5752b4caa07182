// wmd + wm-servosila (the bridge) + wm-servosila-sim (a simulated Servosila Engineer), all real processes on
// loopback: a scripted 2 m square ends with the robot's pose in GET /api/v1/robots/{id} within the odometry's
// stated covariance of the simulator's truth; SIGTERM makes the simulator see a stop within 200 ms; SIGKILL
// leaves it to the simulator's own watchdog; with 20 % packet loss the robot still stops when the script ends.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <boost/asio/connect.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cmath>
#include <functional>
#include <iostream>
#include <mutex>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

/// A child process whose stdout and stderr lines are collected, each with the time it arrived, by a thread.
class Child {
 public:
  struct Line {
    Clock::time_point at;
    std::string text;
  };

  explicit Child(std::vector<std::string> args) {
    int out[2];
    if (::pipe2(out, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDERR_FILENO);
    posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, args[0].c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    if (rc != 0) {
      ::close(out[0]);
      throw std::runtime_error("cannot start " + args[0]);
    }
    reader_ = std::thread([this, fd = out[0]] { read_lines(fd); });
  }
  ~Child() {
    if (!status_) {
      ::kill(pid_, SIGKILL);
      wait(std::chrono::seconds(5));
    }
    reader_.join();
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  void signal(int s) const { ::kill(pid_, s); }

  /// The exit status (128 + N after signal N), or nothing when still running after `timeout`.
  std::optional<int> wait(Clock::duration timeout) {
    const Clock::time_point deadline = Clock::now() + timeout;
    while (!status_) {
      int raw = 0;
      if (::waitpid(pid_, &raw, WNOHANG) == pid_) {
        status_ = WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw);
      } else if (Clock::now() > deadline) {
        return std::nullopt;
      } else {
        std::this_thread::sleep_for(milliseconds(10));
      }
    }
    return status_;
  }

  std::vector<Line> lines() const {
    const std::lock_guard lock(mutex_);
    return lines_;
  }
  std::string output() const {
    std::string text;
    for (const auto& line : lines()) text += line.text + "\n";
    return text;
  }
  /// The first line from index `from` on that satisfies `match`, waiting up to `timeout` for it.
  std::optional<std::size_t> find_line(const std::function<bool(const std::string&)>& match, Clock::duration timeout,
                                       std::size_t from = 0) const {
    const Clock::time_point deadline = Clock::now() + timeout;
    for (;;) {
      {
        const std::lock_guard lock(mutex_);
        for (std::size_t i = from; i < lines_.size(); ++i) {
          if (match(lines_[i].text)) return i;
        }
      }
      if (Clock::now() > deadline) return std::nullopt;
      std::this_thread::sleep_for(milliseconds(2));
    }
  }

 private:
  void read_lines(int fd) {
    std::string pending;
    char buffer[4096];
    for (;;) {
      const ssize_t n = ::read(fd, buffer, sizeof buffer);
      if (n <= 0) break;
      const Clock::time_point now = Clock::now();
      pending.append(buffer, static_cast<std::size_t>(n));
      const std::lock_guard lock(mutex_);
      for (std::size_t eol = pending.find('\n'); eol != std::string::npos; eol = pending.find('\n')) {
        lines_.push_back({now, pending.substr(0, eol)});
        pending.erase(0, eol + 1);
      }
    }
    ::close(fd);
  }

  pid_t pid_ = -1;
  std::optional<int> status_;
  std::thread reader_;
  mutable std::mutex mutex_;
  std::vector<Line> lines_;
};

/// wm-servosila-sim on an ephemeral port; its true pose comes as JSON lines.
class Sim : public Child {
 public:
  explicit Sim(const std::vector<std::string>& extra) : Child(with_defaults(extra)) {
    const auto line = find_line([](const std::string& l) { return l.find("listening on") != std::string::npos; },
                                std::chrono::seconds(10));
    if (!line) throw std::runtime_error("wm-servosila-sim did not start: " + output());
    const std::string text = lines()[*line].text;
    port_ = std::stoi(text.substr(text.rfind(' ') + 1));
  }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }

  /// The truth lines, parsed.
  std::vector<std::pair<Clock::time_point, json>> truth() const {
    std::vector<std::pair<Clock::time_point, json>> result;
    for (const auto& line : lines()) {
      if (!line.text.empty() && line.text.front() == '{') result.emplace_back(line.at, json::parse(line.text));
    }
    return result;
  }
  json last_truth() const {
    const auto all = truth();
    if (all.empty()) throw std::runtime_error("no truth from the simulator: " + output());
    return all.back().second;
  }

 private:
  static std::vector<std::string> with_defaults(const std::vector<std::string>& extra) {
    std::vector<std::string> args{WM_SERVOSILA_SIM_PATH, "--port", "0", "--telemetry-period", "0.1"};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
  int port_ = 0;
};

bool sim_moving(const std::string& line) {
  if (line.empty() || line.front() != '{') return false;
  const json j = json::parse(line);
  return j["linear_mps"].get<double>() != 0.0 || j["angular_radps"].get<double>() != 0.0;
}
bool sim_stopped(const std::string& line) { return !line.empty() && line.front() == '{' && !sim_moving(line); }

double wrap_angle(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

/// The server's pose against the simulator's truth: each of x, y and θ within 3σ of the covariance the bridge
/// stated, and within 0.5 m (or 0.1 rad) whatever it stated.
void expect_pose_near_truth(const json& pose, const json& truth, const std::string& what) {
  const double dx = pose["x"].get<double>() - truth["x_m"].get<double>();
  const double dy = pose["y"].get<double>() - truth["y_m"].get<double>();
  const double dtheta = wrap_angle(pose["theta"].get<double>() - truth["theta_rad"].get<double>());
  ASSERT_TRUE(pose.contains("cov")) << pose.dump();
  const double sx = std::sqrt(pose["cov"][0][0].get<double>());
  const double sy = std::sqrt(pose["cov"][1][1].get<double>());
  const double stheta = std::sqrt(pose["cov"][2][2].get<double>());
  std::cout << what << ": pose error dx " << dx << " m (" << std::abs(dx) / sx << " sigma, sigma " << sx << " m), dy "
            << dy << " m (" << std::abs(dy) / sy << " sigma, sigma " << sy << " m), dtheta " << dtheta << " rad ("
            << std::abs(dtheta) / stheta << " sigma, sigma " << stheta << " rad)\n";
  EXPECT_LE(std::abs(dx), 3.0 * sx);
  EXPECT_LE(std::abs(dy), 3.0 * sy);
  EXPECT_LE(std::abs(dtheta), 3.0 * stheta);
  EXPECT_LE(std::hypot(dx, dy), 0.5);
  EXPECT_LE(std::abs(dtheta), 0.1);
}

class ServosilaTest : public ServerFixture {
 protected:
  void SetUp() override {
    extra_args_ = {"--token", token_};
    ServerFixture::SetUp();
  }

  std::vector<std::string> bridge_args(const Sim& sim, const std::string& id, const std::string& drive,
                                       const std::vector<std::string>& extra = {}) const {
    std::vector<std::string> args{WM_SERVOSILA_BRIDGE_PATH,
                                  "--robot",
                                  sim.address(),
                                  "--server",
                                  server_->url(),
                                  "--token",
                                  token_,
                                  "--id",
                                  id,
                                  "--drive",
                                  drive};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }

  const std::string token_ = "servosila-e2e-token";
};

TEST_F(ServosilaTest, ASquareDriveEndsWithTheServersPoseWithinTheOdometrysCovarianceOfTheTruth) {
  Sim sim({"--print-period", "0.05"});
  const auto started = Clock::now();
  // The fastest the protocol allows (int16 axes: 0.455 m/s, 1.365 rad/s), so that the 8 m take 23 s.
  Child bridge(bridge_args(sim, "servosila-e2e", "F 2; L 90; F 2; L 90; F 2; L 90; F 2; L 90",
                           {"--speed", "0.45", "--max-speed", "0.45", "--turn-speed", "1.3", "--max-turn", "1.3",
                            "--pause", "0", "--watchdog", "1.0"}));
  // Halfway round, wmd already knows the robot as moving.
  std::this_thread::sleep_for(std::chrono::seconds(5));
  const json during = get_json("/api/v1/robots/servosila-e2e");
  EXPECT_EQ(during["status"], "alive") << during.dump();
  EXPECT_GT(during["pose"]["x"].get<double>(), 1.0);

  const auto status = bridge.wait(std::chrono::seconds(45));
  ASSERT_TRUE(status.has_value()) << bridge.output();
  EXPECT_EQ(*status, 0) << bridge.output();
  std::this_thread::sleep_for(milliseconds(300));  // the simulator's last truth lines
  const json truth = sim.last_truth();
  EXPECT_FALSE(sim_moving(truth.dump())) << truth.dump();

  const json robot = get_json("/api/v1/robots/servosila-e2e");
  EXPECT_EQ(robot["status"], "stopped") << robot.dump();
  EXPECT_EQ(robot["pose"]["source"], "reported");
  EXPECT_GT(robot["poses"].get<int>(), 50) << "five a second for 23 s";
  EXPECT_GT(robot["track"].size(), 20u);
  std::cout << "square in " << std::chrono::duration<double>(Clock::now() - started).count() << " s; truth "
            << truth.dump() << "\n";
  expect_pose_near_truth(robot["pose"], truth, "square");
  // The truth went round the square: the far corner was (2, 2).
  double max_x = 0.0;
  double max_y = 0.0;
  for (const auto& [at, t] : sim.truth()) {
    max_x = std::max(max_x, t["x_m"].get<double>());
    max_y = std::max(max_y, t["y_m"].get<double>());
    EXPECT_FALSE(t["watchdog_stopped"].get<bool>()) << "the simulator's watchdog never had to stop it";
  }
  EXPECT_NEAR(max_x, 2.0, 0.1);
  EXPECT_NEAR(max_y, 2.0, 0.1);
  // What the bridge printed at exit is what wmd has.
  const auto last_line =
      bridge.find_line([](const std::string& l) { return !l.empty() && l.front() == '{'; }, milliseconds(0));
  ASSERT_TRUE(last_line.has_value()) << bridge.output();
  const json printed = json::parse(bridge.lines()[*last_line].text);
  EXPECT_NEAR(printed["x"].get<double>(), robot["pose"]["x"].get<double>(), 1e-6);
  EXPECT_NEAR(printed["y"].get<double>(), robot["pose"]["y"].get<double>(), 1e-6);
  EXPECT_EQ(printed["odometry"], "tracks");
  EXPECT_NE(bridge.output().find("watchdog_trips=0"), std::string::npos) << bridge.output();
}

TEST_F(ServosilaTest, SigtermMakesTheSimulatorSeeAStopWithin200Milliseconds) {
  // The simulator's own watchdog is 10 s here: only a stop packet can stop it.
  Sim sim({"--print-period", "0.01", "--watchdog", "10"});
  Child bridge(bridge_args(sim, "servosila-term", "F 10", {"--speed", "0.3"}));
  const auto moving = sim.find_line(sim_moving, std::chrono::seconds(5));
  ASSERT_TRUE(moving.has_value()) << sim.output() << bridge.output();
  std::this_thread::sleep_for(milliseconds(500));
  const std::size_t lines_before = sim.lines().size();
  const Clock::time_point killed = Clock::now();
  bridge.signal(SIGTERM);
  const auto stop = sim.find_line(sim_stopped, std::chrono::seconds(2), lines_before);
  ASSERT_TRUE(stop.has_value()) << sim.output() << bridge.output();
  const auto line = sim.lines()[*stop];
  const double delay_ms = std::chrono::duration<double, std::milli>(line.at - killed).count();
  std::cout << "SIGTERM: the simulator saw a stop after " << delay_ms << " ms (its truth is printed every 10 ms)\n";
  EXPECT_LT(delay_ms, 200.0 + 10.0 + 40.0) << "200 ms, plus the simulator's print period and scheduling";
  EXPECT_FALSE(json::parse(line.text)["watchdog_stopped"].get<bool>()) << line.text;

  const auto status = bridge.wait(std::chrono::seconds(5));
  ASSERT_TRUE(status.has_value()) << bridge.output();
  EXPECT_EQ(*status, 128 + SIGTERM) << bridge.output();
  EXPECT_NE(bridge.output().find("signal 15: stopping the robot"), std::string::npos) << bridge.output();
  EXPECT_NE(bridge.output().find("counters: control_sent="), std::string::npos) << bridge.output();
  std::this_thread::sleep_for(milliseconds(300));
  EXPECT_FALSE(sim_moving(sim.last_truth().dump()));
  EXPECT_EQ(get_json("/api/v1/robots/servosila-term")["status"], "stopped");
}

TEST_F(ServosilaTest, SigkillLeavesTheStopToTheSimulatorsWatchdog) {
  // SIGKILL cannot be caught: no stop packet comes, and the simulator's watchdog (0.5 s) stops the robot.
  Sim sim({"--print-period", "0.01", "--watchdog", "0.5"});
  Child bridge(bridge_args(sim, "servosila-kill", "F 10", {"--speed", "0.3"}));
  ASSERT_TRUE(sim.find_line(sim_moving, std::chrono::seconds(5)).has_value()) << sim.output() << bridge.output();
  std::this_thread::sleep_for(milliseconds(500));
  const std::size_t lines_before = sim.lines().size();
  const Clock::time_point killed = Clock::now();
  bridge.signal(SIGKILL);
  const auto stop = sim.find_line(sim_stopped, std::chrono::seconds(3), lines_before);
  ASSERT_TRUE(stop.has_value()) << sim.output();
  const auto line = sim.lines()[*stop];
  const double delay_ms = std::chrono::duration<double, std::milli>(line.at - killed).count();
  std::cout << "SIGKILL: the simulator's watchdog stopped the robot after " << delay_ms << " ms\n";
  EXPECT_TRUE(json::parse(line.text)["watchdog_stopped"].get<bool>()) << line.text;
  EXPECT_GT(delay_ms, 200.0) << "the last control packet came at most 200 ms before the kill, the watchdog is 500";
  EXPECT_LT(delay_ms, 1500.0);
  EXPECT_EQ(bridge.wait(std::chrono::seconds(5)), 128 + SIGKILL);
}

TEST_F(ServosilaTest, WithTwentyPercentLossTheRobotStillStopsWhenTheScriptEnds) {
  // Loss and reordering both ways; the simulator's watchdog is 10 s, so only a stop packet can stop it.
  Sim sim({"--print-period", "0.05", "--loss", "0.2", "--reorder", "0.1", "--seed", "16", "--watchdog", "10"});
  Child bridge(bridge_args(sim, "servosila-loss", "F 0.6; L 90; F 0.4",
                           {"--speed", "0.4", "--turn-speed", "1.0", "--pause", "0", "--watchdog", "1.5"}));
  const auto status = bridge.wait(std::chrono::seconds(20));
  ASSERT_TRUE(status.has_value()) << bridge.output();
  EXPECT_EQ(*status, 0) << bridge.output();
  // The bridge is gone; nothing else will ever tell the robot to stop. It stays stopped.
  std::this_thread::sleep_for(milliseconds(700));
  const json truth = sim.last_truth();
  EXPECT_FALSE(sim_moving(truth.dump())) << truth.dump() << "\n" << bridge.output();
  EXPECT_FALSE(truth["watchdog_stopped"].get<bool>());
  EXPECT_GT(truth["y_m"].get<double>(), 0.3) << "it did turn left and drive on";
  const json robot = get_json("/api/v1/robots/servosila-loss");
  EXPECT_EQ(robot["status"], "stopped") << robot.dump();
  expect_pose_near_truth(robot["pose"], truth, "20 % loss");
}

}  // namespace
}  // namespace wm::testing

namespace wm::testing {
namespace {

/// A driver of GET /api/v1/robots/{id}/drive that only writes (wmd's state messages are not read).
class Driver {
 public:
  Driver(int port, const std::string& robot, const std::string& token) : ws_(ioc_) {
    boost::asio::ip::tcp::resolver resolver(ioc_);
    boost::asio::connect(ws_.next_layer(), resolver.resolve("127.0.0.1", std::to_string(port)));
    ws_.set_option(boost::beast::websocket::stream_base::decorator([token](boost::beast::websocket::request_type& r) {
      r.set(boost::beast::http::field::authorization, "Bearer " + token);
    }));
    ws_.handshake("127.0.0.1", "/api/v1/robots/" + robot + "/drive");
  }
  bool send(double v, double w) {
    boost::beast::error_code ec;
    ws_.write(boost::asio::buffer(json{{"v", v}, {"w", w}}.dump()), ec);
    return !ec;
  }

 private:
  boost::asio::io_context ioc_;
  boost::beast::websocket::stream<boost::asio::ip::tcp::socket> ws_;
};

TEST_F(ServosilaTest, ADriverThroughWmdMovesTheSimulatorTelemetryShowsAFaultAndLosingWmdStopsIt) {
  Sim sim({"--print-period", "0.01", "--watchdog", "10"});
  Child bridge({WM_SERVOSILA_BRIDGE_PATH, "--robot", sim.address(), "--server", server_->url(), "--token", token_,
                "--id", "remote-1", "--remote-drive"});
  ASSERT_TRUE(bridge.find_line([](const std::string& l) { return l.find("connected to") != std::string::npos; },
                               std::chrono::seconds(10)))
      << bridge.output();
  Driver driver(server_->port(), "remote-1", token_);
  const auto drive_for = [&](Clock::duration d) {
    for (const auto end = Clock::now() + d; Clock::now() < end; std::this_thread::sleep_for(milliseconds(100)))
      driver.send(0.3, 0.0);
  };
  drive_for(milliseconds(1000));
  ASSERT_TRUE(sim.find_line(sim_moving, std::chrono::seconds(1))) << sim.output() << bridge.output();
  EXPECT_GT(sim.last_truth()["x_m"].get<double>(), 0.1);

  // The telemetry the bridge decodes reaches wmd with the pose; a fault raised in the simulator turns the status.
  sim.signal(SIGUSR1);
  json robot;
  for (int i = 0; i < 100; ++i) {
    drive_for(milliseconds(100));
    robot = get_json("/api/v1/robots/remote-1");
    if (robot["status"] == "fault") break;
  }
  ASSERT_EQ(robot["status"], "fault") << robot.dump();
  ASSERT_EQ(robot["telemetry"]["motors"].size(), 2u) << robot.dump();
  EXPECT_GT(robot["telemetry"]["motors"][0]["current"].get<double>(), 0.0) << "the tracks draw current while moving";
  EXPECT_TRUE(robot["telemetry"]["motors"][0]["temperature"].is_null()) << "the protocol has no temperatures";
  EXPECT_EQ(robot["telemetry"]["motors"][0]["faults"], 1);
  EXPECT_EQ(robot["drive"]["robot_connected"], true);

  // wmd killed mid-drive: the bridge's connection ends, and it stops the robot.
  drive_for(milliseconds(300));
  ASSERT_TRUE(sim_moving(sim.last_truth().dump()));
  const std::size_t lines_before = sim.lines().size();
  const Clock::time_point killed = Clock::now();
  server_->crash();
  const auto stop = sim.find_line(sim_stopped, std::chrono::seconds(3), lines_before);
  ASSERT_TRUE(stop.has_value()) << sim.output() << bridge.output();
  const double delay_ms = std::chrono::duration<double, std::milli>(sim.lines()[*stop].at - killed).count();
  std::cout << "wmd killed: the simulator saw a stop after " << delay_ms << " ms\n";
  EXPECT_FALSE(json::parse(sim.lines()[*stop].text)["watchdog_stopped"].get<bool>());
  bridge.signal(SIGTERM);
  EXPECT_TRUE(bridge.wait(std::chrono::seconds(10)).has_value()) << bridge.output();
  start();  // the fixture's teardown expects a server
}

}  // namespace
}  // namespace wm::testing
