#pragma once

#include <gtest/gtest.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "clients/wmctl/http_client.h"
#include "support/test_data.h"
#include "support/wmd_process.h"

namespace wm::testing {

using nlohmann::json;
using Headers = std::vector<std::pair<std::string, std::string>>;

/// One HTTP/1.1 request on a fresh loopback connection to `port`, with exactly the headers given (Host, Origin,
/// Idempotency-Key...; the HttpClient sets its own) and a JSON body when `body` is not empty.
/// @throw boost::system::system_error when no whole answer comes back within `timeout` (refused, reset, timed out).
inline boost::beast::http::response<boost::beast::http::string_body> raw_request(
    int port, boost::beast::http::verb method, const std::string& target, const Headers& headers,
    const std::string& body = {}, std::chrono::milliseconds timeout = std::chrono::seconds(60)) {
  namespace beast = boost::beast;
  namespace net = boost::asio;
  net::io_context ioc;
  beast::tcp_stream stream(ioc);
  stream.expires_after(timeout);
  stream.connect(net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)));
  beast::http::request<beast::http::string_body> req{method, target, 11};
  for (const auto& [name, value] : headers) req.set(name, value);
  if (!body.empty()) {
    req.set(beast::http::field::content_type, "application/json");
    req.body() = body;
  }
  req.prepare_payload();
  beast::http::write(stream, req);
  beast::flat_buffer buffer;
  beast::http::response<beast::http::string_body> res;
  beast::http::read(stream, buffer, res);
  beast::error_code ignored;
  stream.socket().shutdown(net::ip::tcp::socket::shutdown_both, ignored);
  return res;
}

/// The whole content of a file ("" when it cannot be read).
inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The shell command that runs wmctl against `server` with `args`.
inline std::string wmctl(const std::string& server, const std::string& args) {
  return std::string(WM_WMCTL_PATH) + " --server " + server + " " + args;
}

/// The lab of the foundation issue: a solid wall, a rotated not_deformable table, free space elsewhere.
inline json lab_plan() {
  return json::parse(R"({
    "name": "lab-e2e", "units": "m",
    "objects": [
      {"id": "wall-n", "kind": "wall", "attributes": ["solid"], "pose": {"x": 0, "y": 0, "theta": 0},
       "segments": [[[0, 10], [20, 10]]]},
      {"id": "table-1", "kind": "table", "attributes": ["not_deformable"], "pose": {"x": 5, "y": 5, "theta": 0.3},
       "polygon": [[-0.6, -0.4], [0.6, -0.4], [0.6, 0.4], [-0.6, 0.4]]}]})");
}

/// A client of GET /api/v1/events (the WebSocket): next() blocks for the next event.
class EventClient {
 public:
  /// `target`: another map's events, /api/v1/maps/{map}/events.
  explicit EventClient(int port, const std::string& target = "/api/v1/events") : ws_(ioc_) {
    boost::asio::ip::tcp::resolver resolver(ioc_);
    boost::asio::connect(ws_.next_layer(), resolver.resolve("127.0.0.1", std::to_string(port)));
    ws_.handshake("127.0.0.1", target);
  }
  json next() {
    boost::beast::flat_buffer buffer;
    ws_.read(buffer);
    return json::parse(boost::beast::buffers_to_string(buffer.data()));
  }
  /// The next event of `type`, skipping others (at most `limit` of them).
  json next_of(const std::string& type, int limit = 100) {
    for (int i = 0; i < limit; ++i)
      if (auto event = next(); event["type"] == type) return event;
    throw std::runtime_error("no " + type + " event among the next " + std::to_string(limit));
  }

 private:
  boost::asio::io_context ioc_;
  boost::beast::websocket::stream<boost::asio::ip::tcp::socket> ws_;
};

/// Starts wmd on a fresh database in a temporary directory; restart() keeps the file.
class ServerFixture : public ::testing::Test {
 protected:
  void SetUp() override { start(); }

  void start() {
    std::vector<std::string> args{"--db", (dir_.path() / "wm.db").string(), "--port", "0", "--rules", rules_dir_};
    args.insert(args.end(), extra_args_.begin(), extra_args_.end());
    server_ = std::make_unique<WmdProcess>(args);
    client_ = std::make_unique<client::HttpClient>(server_->url());
  }
  // Before start(): wmd runs on a private copy of the shipped rules in dir_/rules, which the test may edit.
  void use_rules_copy() {
    const auto rules = dir_.path() / "rules";
    std::filesystem::create_directories(rules);
    std::filesystem::copy_file(std::filesystem::path(WM_RULES_DIR) / "world_model.pl", rules / "world_model.pl");
    rules_dir_ = rules.string();
  }
  void restart() {
    ASSERT_EQ(server_->stop(), 0) << server_->output();
    start();
  }

  client::HttpResult call(const std::string& method, const std::string& target, const std::string& body = {},
                          const std::string& type = "application/json") {
    return client_->request(method, target, body, type);
  }
  json get_json(const std::string& target) {
    auto r = call("GET", target);
    EXPECT_EQ(r.status, 200) << r.body;
    return json::parse(r.body);
  }
  json send_json(const std::string& method, const std::string& target, const json& body, int expected_status = 200) {
    auto r = call(method, target, body.dump());
    EXPECT_EQ(r.status, expected_status) << r.body;
    return json::parse(r.body);
  }

  TempDir dir_;
  std::string rules_dir_ = WM_RULES_DIR;
  std::vector<std::string> extra_args_;
  std::unique_ptr<WmdProcess> server_;
  std::unique_ptr<client::HttpClient> client_;
};

}  // namespace wm::testing
