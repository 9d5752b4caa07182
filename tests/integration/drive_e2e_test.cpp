// GET /api/v1/robots/{id}/drive against a real wmd over loopback: a robot side and drivers as WebSocket clients,
// the relay's clamping, hold lease and stops, hostile drivers, and the telemetry of PUT /api/v1/robots/{id}/pose.
#include <gtest/gtest.h>

#include <algorithm>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstdio>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "tests/integration/e2e_fixture.h"

namespace wm::testing {
namespace {

namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

constexpr const char* kToken = "s3cret";

/// A WebSocket client with timed reads.
class Ws {
 public:
  /// Handshakes; `status` is the HTTP answer (101 when upgraded).
  Ws(int port, const std::string& target, const std::string& token = kToken) : ws_(ioc_) {
    beast::get_lowest_layer(ws_).connect(
        net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)));
    ws_.set_option(websocket::stream_base::decorator([token](websocket::request_type& r) {
      if (!token.empty()) r.set(beast::http::field::authorization, "Bearer " + token);
    }));
    ws_.read_message_max(1 << 22);
    websocket::response_type res;
    beast::error_code ec;
    ws_.handshake(res, "127.0.0.1:" + std::to_string(port), target, ec);
    status = static_cast<int>(res.result_int());
    body = res.body();
  }
  /// The next message within `timeout`; nullopt on timeout or a closed connection (then `closed`).
  std::optional<json> read(milliseconds timeout = milliseconds(2000)) {
    std::optional<json> message;
    bool done = false;
    ws_.async_read(buffer_, [&](beast::error_code ec, std::size_t) {
      done = true;
      if (ec) {
        closed = true;
        return;
      }
      message = json::parse(beast::buffers_to_string(buffer_.data()), nullptr, false);
      buffer_.consume(buffer_.size());
    });
    ioc_.restart();
    ioc_.run_for(timeout);
    if (!done) {
      beast::get_lowest_layer(ws_).cancel();
      ioc_.restart();
      ioc_.run();
      closed = false;
    }
    return message;
  }
  /// The next message satisfying `want` within `timeout`, skipping others.
  std::optional<json> read_until(const std::function<bool(const json&)>& want,
                                 milliseconds timeout = milliseconds(2000)) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      auto m = read(std::chrono::duration_cast<milliseconds>(deadline - Clock::now()) + milliseconds(1));
      if (!m) return std::nullopt;
      if (want(*m)) return m;
    }
    return std::nullopt;
  }
  bool send(const std::string& text, bool binary = false) {
    beast::error_code ec;
    ws_.binary(binary);
    ws_.write(net::buffer(text), ec);
    return !ec;
  }
  void close() {
    beast::error_code ec;
    ws_.close(websocket::close_code::normal, ec);
  }

  int status = 0;
  std::string body;
  bool closed = false;

 private:
  net::io_context ioc_;
  websocket::stream<beast::tcp_stream> ws_;
  beast::flat_buffer buffer_;
};

bool is_command(const json& m, double v, double w) {
  return m.is_object() && m.contains("v") && m.contains("w") && !m.contains("type") && m["v"] == v && m["w"] == w;
}
bool is_stop(const json& m) { return is_command(m, 0.0, 0.0); }
bool is_error(const json& m) { return m.is_object() && m.value("type", "") == "error"; }

class DriveE2eTest : public ServerFixture {
 protected:
  void SetUp() override {
    extra_args_ = {"--token", kToken, "--drive-max-speed", "0.4", "--drive-max-turn", "1.25", "--drive-hold-ms", "150"};
    start();
  }
  int port() const { return server_->port(); }
  std::string robot_target(const std::string& id = "r1") const { return "/api/v1/robots/" + id + "/drive?role=robot"; }
  std::string driver_target(const std::string& id = "r1") const {
    return "/api/v1/robots/" + id + "/drive?role=driver";
  }
  client::HttpResult put_pose(const std::string& id, const std::string& body) {
    return client_->request("PUT", "/api/v1/robots/" + id + "/pose", body, "application/json", kToken);
  }
};

TEST_F(DriveE2eTest, UpgradesWithoutTokenOrWithABadIdOrRoleAreRefusedBeforeTheUpgrade) {
  const auto refusal = [&](const std::string& target, const std::string& token) {
    Headers headers{{"Host", "127.0.0.1:" + std::to_string(port())},
                    {"Upgrade", "websocket"},
                    {"Connection", "Upgrade"},
                    {"Sec-WebSocket-Version", "13"},
                    {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="}};
    if (!token.empty()) headers.push_back({"Authorization", "Bearer " + token});
    const auto r = raw_request(port(), beast::http::verb::get, target, headers);
    EXPECT_TRUE(r.result_int() == 101 || json::parse(r.body(), nullptr, false).contains("error")) << r.body();
    return static_cast<int>(r.result_int());
  };
  EXPECT_EQ(refusal(driver_target(), ""), 401);
  EXPECT_EQ(refusal(driver_target(), "wrong"), 401);
  EXPECT_EQ(refusal("/api/v1/robots/r1/drive?role=king", kToken), 400);
  EXPECT_EQ(refusal("/api/v1/robots/bad%20id/drive", kToken), 400);
  EXPECT_EQ(refusal(driver_target(), kToken), 101);
  EXPECT_EQ(Ws(port(), "/api/v1/robots/r1/drive?token=s3cret", "").status, 101) << "?token= for browsers";
  const auto plain = call("GET", "/api/v1/robots/r1/drive");
  EXPECT_EQ(plain.status, 426) << plain.body;
}

TEST_F(DriveE2eTest, CommandsAreClampedRelayedAndStoppedOnReleaseLeaseAndClose) {
  Ws robot(port(), robot_target());
  ASSERT_EQ(robot.status, 101);
  ASSERT_TRUE(robot.read_until(is_stop)) << "a robot is told stop when it connects";
  Ws driver(port(), driver_target());
  ASSERT_EQ(driver.status, 101);
  const auto hello = driver.read();
  ASSERT_TRUE(hello);
  EXPECT_EQ((*hello)["type"], "state");
  EXPECT_EQ((*hello)["robot_connected"], true);
  EXPECT_EQ((*hello)["max_v"], 0.4);
  EXPECT_EQ((*hello)["max_w"], 1.25);
  EXPECT_EQ((*hello)["hold_ms"], 150);

  // Clamped to wmd's limits.
  driver.send(R"({"v": 5, "w": -9})");
  EXPECT_TRUE(robot.read_until([](const json& m) { return is_command(m, 0.4, -1.25); }));
  // Released: a stop at once.
  driver.send(R"({"v": 0, "w": 0})");
  EXPECT_TRUE(robot.read_until(is_stop, milliseconds(100)));

  // Held, then silent: the lease stops it (150 ms).
  std::vector<double> lease_ms;
  for (int i = 0; i < 5; ++i) {
    driver.send(R"({"v": 0.3, "w": 0})");
    const auto sent = Clock::now();
    ASSERT_TRUE(robot.read_until([](const json& m) { return is_command(m, 0.3, 0.0); }));
    ASSERT_TRUE(robot.read_until(is_stop, milliseconds(2000))) << "the hold lease stops it";
    lease_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - sent).count());
  }
  for (const double ms : lease_ms) {
    EXPECT_GE(ms, 140.0);
    EXPECT_LT(ms, 200.0) << "the stated bound: a stop within 200 ms of the last command";
  }
  std::printf("hold lease: stop %0.f..%0.f ms after the last driver command\n",
              *std::min_element(lease_ms.begin(), lease_ms.end()), *std::max_element(lease_ms.begin(), lease_ms.end()));

  // The driver goes away mid-command: a stop at once.
  // The stop must come before the 150 ms lease (measured from the last command) could give it.
  driver.send(R"({"v": 0.3, "w": 0.5})");
  const auto last_command = Clock::now();
  ASSERT_TRUE(robot.read_until([](const json& m) { return is_command(m, 0.3, 0.5); }));
  const auto closing = Clock::now();
  driver.close();
  ASSERT_TRUE(robot.read_until(is_stop, milliseconds(500)));
  const auto stopped = Clock::now();
  std::printf("driver closed: stop after %.1f ms\n",
              std::chrono::duration<double, std::milli>(stopped - closing).count());
  EXPECT_LT((std::chrono::duration<double, std::milli>(stopped - last_command).count()), 140.0)
      << "the close's own stop, not the hold lease";
}

TEST_F(DriveE2eTest, HostileDriverMessagesAreStopsAndErrorsNeverMotion) {
  Ws robot(port(), robot_target());
  ASSERT_TRUE(robot.read_until(is_stop));
  Ws driver(port(), driver_target());
  ASSERT_TRUE(driver.read());
  for (const std::string& bad :
       std::vector<std::string>{"not json", R"({"v": NaN, "w": 0})", R"({"v": "0.3", "w": 0})", R"({"v": 0.3})",
                                R"({"v": 0.3, "w": 0, "x": 1})", R"([0.3, 0])", R"({"v": 1e400, "w": 0})",
                                R"({"v": 1e308, "w": 0})", R"({"v": null, "w": 0})", std::string(8192, ' ') + "{}",
                                // a 3-byte UTF-8 character across the 64-byte cut of an unknown key
                                R"({"v": 0.3, "w": 0, ")" + std::string(63, 'k') + "\xe2\x82\xac" + R"(": 1})"}) {
    driver.send(R"({"v": 0.3, "w": 0})");
    ASSERT_TRUE(robot.read_until([](const json& m) { return is_command(m, 0.3, 0.0); })) << bad;
    driver.send(bad);
    EXPECT_TRUE(robot.read_until(is_stop, milliseconds(100))) << "a stop at once for: " << bad.substr(0, 40);
    EXPECT_TRUE(driver.read_until(is_error)) << bad.substr(0, 40);
  }
  driver.send(R"({"v": 0.3, "w": 0})");
  ASSERT_TRUE(robot.read_until([](const json& m) { return is_command(m, 0.3, 0.0); }));
  driver.send("\x01\x02", true);
  EXPECT_TRUE(robot.read_until(is_stop, milliseconds(100))) << "binary";
}

TEST_F(DriveE2eTest, OneDriverAtATimeFloodsAndOversizedFramesDoNotHurt) {
  Ws robot(port(), robot_target());
  ASSERT_TRUE(robot.read_until(is_stop));
  Ws first(port(), driver_target());
  ASSERT_TRUE(first.read());
  Ws second(port(), driver_target());
  ASSERT_EQ(second.status, 101);
  const auto refusal = second.read();
  ASSERT_TRUE(refusal);
  EXPECT_EQ((*refusal)["error"], "driver_busy");
  EXPECT_FALSE(second.read(milliseconds(500))) << "then closed";

  // A flood of commands: relayed (each renews the lease), then the lease stops the robot.
  for (int i = 0; i < 5000; ++i) ASSERT_TRUE(first.send(R"({"v": 0.2, "w": 0})"));
  ASSERT_TRUE(robot.read_until(is_stop, milliseconds(10000))) << "the lease after the flood";
  EXPECT_EQ(call("GET", "/api/v1/health").status, 200);

  // A frame over the transport's 1 MiB: the connection ends, which is a stop.
  first.send(R"({"v": 0.3, "w": 0})");
  ASSERT_TRUE(robot.read_until([](const json& m) { return is_command(m, 0.3, 0.0); }));
  first.send(std::string(2 << 20, 'x'));
  EXPECT_TRUE(robot.read_until(is_stop, milliseconds(1000)));
  // The slot is free again.
  Ws third(port(), driver_target());
  const auto state = third.read();
  ASSERT_TRUE(state);
  EXPECT_EQ((*state)["type"], "state");
}

TEST_F(DriveE2eTest, ADriverSilentForThreeSecondsGivesWayToANewOne) {
  Ws robot(port(), robot_target());
  ASSERT_TRUE(robot.read_until(is_stop));
  Ws first(port(), driver_target());
  ASSERT_TRUE(first.read());
  first.send(R"({"v": 0.3, "w": 0})");
  ASSERT_TRUE(robot.read_until([](const json& m) { return is_command(m, 0.3, 0.0); }));
  ASSERT_TRUE(robot.read_until(is_stop)) << "the lease";
  std::this_thread::sleep_for(milliseconds(3200));  // a half-open connection, a forgotten tab
  Ws second(port(), driver_target());
  const auto state = second.read();
  ASSERT_TRUE(state);
  EXPECT_EQ((*state)["type"], "state") << state->dump();
  const auto told = first.read_until(is_error);
  ASSERT_TRUE(told);
  EXPECT_EQ((*told)["error"], "replaced");
  second.send(R"({"v": -0.2, "w": 0})");
  EXPECT_TRUE(robot.read_until([](const json& m) { return is_command(m, -0.2, 0.0); }));
  first.send(R"({"v": 0.3, "w": 0})");
  EXPECT_FALSE(robot.read_until([](const json& m) { return is_command(m, 0.3, 0.0); }, milliseconds(300)))
      << "the replaced driver drives no more";
}

TEST_F(DriveE2eTest, TelemetryIsValidatedServedAndAFaultTurnsTheStatus) {
  const json pose = {{"x", 1.0}, {"y", 2.0}, {"theta", 0.0}};
  ASSERT_EQ(put_pose("r1", pose.dump()).status, 200);
  auto robot = get_json("/api/v1/robots/r1");
  EXPECT_TRUE(robot["telemetry"].is_null());
  EXPECT_EQ(robot["status"], "alive");
  EXPECT_EQ(robot["drive"]["max_v"], 0.4);

  const auto with = [&](json telemetry) {
    json body = pose;
    body["x"] = 7.0;
    body["telemetry"] = std::move(telemetry);
    return body.dump();
  };
  const json motor = {{"id", 0}, {"current", 120}, {"temperature", nullptr}, {"fault", false}, {"faults", 0}};
  for (const auto& bad : std::vector<std::string>{
           with(json::array()), with({{"motors", json::array({json{{"id", "0"}}})}}),
           with({{"motors", json::array({json{{"id", 0}, {"current", "high"}}})}}),
           with({{"motors", json::array({json{{"id", 0}, {"fault", 1}}})}}),
           with({{"motors", json::array({json{{"id", 300}}})}}), with({{"motors", json::array({json{{"id", -1}}})}}),
           with({{"motors", json::array({json{{"current", 1}}})}}), with({{"motors", json(17, motor)}}),
           with({{"motors", json::array({motor})}, {"extra", 1}}),
           R"({"x": 7, "y": 2, "theta": 0, "telemetry": {"motors": [{"id": 0, "current": 1e400}]}})",
           with({{"motors", json::array({json{{"id", 0}, {"current", 1e300}}})}})}) {
    const auto r = put_pose("r1", bad);
    EXPECT_EQ(r.status, 400) << bad.substr(0, 200) << " -> " << r.body;
    EXPECT_EQ(json::parse(r.body, nullptr, false).value("error", ""), "bad_request") << r.body;
  }
  robot = get_json("/api/v1/robots/r1");
  EXPECT_EQ(robot["pose"]["x"], 1.0) << "a refused report changes nothing";
  EXPECT_TRUE(robot["telemetry"].is_null());

  ASSERT_EQ(put_pose("r1", with({{"motors", json::array({motor, json{{"id", 1}, {"fault", true}, {"faults", 3}}})},
                                 {"current_unit", "raw"}}))
                .status,
            200);
  robot = get_json("/api/v1/robots/r1");
  EXPECT_EQ(robot["status"], "fault");
  EXPECT_EQ(robot["telemetry"]["fault"], true);
  EXPECT_EQ(robot["telemetry"]["motors"][1]["faults"], 3);
  EXPECT_TRUE(robot["telemetry"]["motors"][1]["temperature"].is_null());
  EXPECT_EQ(robot["telemetry"]["motors"][0]["current"], 120);
  const auto listed = get_json("/api/v1/robots");
  EXPECT_EQ(listed["robots"][0]["status"], "fault");

  ASSERT_EQ(put_pose("r1", with({{"motors", json::array({motor})}})).status, 200);
  EXPECT_EQ(get_json("/api/v1/robots/r1")["status"], "alive") << "cleared by the next report without a fault";
}

}  // namespace
}  // namespace wm::testing
