#include "clients/robot/remote_drive.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <stdexcept>
#include <thread>

#include "clients/robot/servosila_bridge.h"

namespace wm::robot {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using Clock = std::chrono::steady_clock;

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

/// {"v", "w"} finite numbers; nullopt for anything else.
std::optional<std::pair<double, double>> parse_command(const std::string& text) {
  if (text.size() > 4096) return std::nullopt;
  const auto j = nlohmann::json::parse(text, nullptr, false);
  if (!j.is_object() || !j.contains("v") || !j.contains("w") || !j["v"].is_number() || !j["w"].is_number())
    return std::nullopt;
  const double v = j["v"].get<double>(), w = j["w"].get<double>();
  if (!std::isfinite(v) || !std::isfinite(w)) return std::nullopt;
  return std::pair{v, w};
}

}  // namespace

struct RemoteDrive::Impl {
  RemoteDriveOptions options;
  std::function<void(double, double)> apply;
  std::string host, port;
  asio::io_context io;
  std::optional<websocket::stream<beast::tcp_stream>> ws;
  asio::steady_timer tick{io};
  beast::flat_buffer buffer;
  Clock::time_point last_command;
  bool moving = false;
  bool is_connected = false;
  bool quit = false;  // on the io thread only
  Clock::time_point reconnect_at;
  mutable std::mutex mutex;  // guards stats and is_connected for readers on other threads
  RemoteDriveStats stats;
  std::thread thread;

  void log(const std::string& line) {
    if (options.log)
      options.log(line);
    else
      std::fprintf(stderr, "wm-servosila: remote drive: %s\n", line.c_str());
  }

  void hand_on(double v, double w) {
    moving = v != 0.0 || w != 0.0;
    last_command = Clock::now();
    apply(v, w);
  }

  void connect() {
    ws.emplace(io);
    buffer.consume(buffer.size());
    tcp::resolver resolver(io);
    beast::error_code ec;
    const auto found = resolver.resolve(host, port, ec);
    if (!ec) beast::get_lowest_layer(*ws).expires_after(std::chrono::seconds(3));
    if (!ec) beast::get_lowest_layer(*ws).connect(found, ec);
    if (ec) return fail("cannot connect to " + host + ":" + port + ": " + ec.message());
    beast::get_lowest_layer(*ws).expires_never();
    ws->set_option(websocket::stream_base::timeout::suggested(beast::role_type::client));
    ws->read_message_max(4096);
    const std::string token = options.token;
    ws->set_option(websocket::stream_base::decorator([token](websocket::request_type& r) {
      r.set(beast::http::field::user_agent, "wm-servosila");
      if (!token.empty()) r.set(beast::http::field::authorization, "Bearer " + token);
    }));
    // The handshake blocks (a few ms on a LAN); reading is asynchronous below.
    const std::string authority = (host.find(':') != std::string::npos ? "[" + host + "]" : host) + ":" + port;
    ws->handshake(authority, "/api/v1/robots/" + options.robot_id + "/drive?role=robot", ec);
    if (ec) return fail("WebSocket handshake with " + host + ":" + port + " refused: " + ec.message());
    {
      const std::lock_guard lock(mutex);
      ++stats.connects;
      is_connected = true;
    }
    log("connected to " + options.server_url + " for drivers of robot '" + options.robot_id + "'");
    read();
  }

  void read() {
    ws->async_read(buffer, [this](beast::error_code ec, std::size_t) {
      if (ec) return fail("connection lost: " + ec.message());
      const auto command = parse_command(beast::buffers_to_string(buffer.data()));
      buffer.consume(buffer.size());
      if (command) {
        {
          const std::lock_guard lock(mutex);
          ++stats.commands;
        }
        hand_on(command->first, command->second);
      } else {  // an error message from wmd, or garbage: a stop
        {
          const std::lock_guard lock(mutex);
          ++stats.refused;
        }
        if (moving) hand_on(0.0, 0.0);
      }
      read();
    });
  }

  void fail(const std::string& why) {
    bool was = false;
    {
      const std::lock_guard lock(mutex);
      was = is_connected;
      is_connected = false;
      if (was) ++stats.disconnects;
    }
    if (was) log(why + "; stop, reconnecting");
    if (moving) hand_on(0.0, 0.0);
    reconnect_at = Clock::now() + seconds(options.reconnect_s);
    asio::post(io, [this] { ws.reset(); });  // not inside one of the stream's own handlers
  }

  void on_tick() {
    tick.expires_after(std::chrono::milliseconds(10));
    tick.async_wait([this](beast::error_code ec) {
      if (ec) return;
      if (moving && Clock::now() - last_command > seconds(options.hold_s)) {
        {
          const std::lock_guard lock(mutex);
          ++stats.hold_stops;
        }
        hand_on(0.0, 0.0);
      }
      if (!ws && !quit && Clock::now() >= reconnect_at) connect();
      on_tick();
    });
  }
};

std::optional<DriveServer> parse_drive_server(const std::string& url) {
  static const std::regex pattern(R"(^http://([A-Za-z0-9._-]+|\[[0-9a-fA-F:.]+\])(?::([0-9]{1,5}))?/?$)");
  std::smatch m;
  if (!std::regex_match(url, m, pattern)) return std::nullopt;
  DriveServer server{m[1].str(), m[2].matched ? m[2].str() : "80"};
  if (server.host.front() == '[') server.host = server.host.substr(1, server.host.size() - 2);
  return server;
}

RemoteDrive::RemoteDrive(RemoteDriveOptions options, std::function<void(double, double)> apply)
    : impl_(std::make_unique<Impl>()) {
  const auto server = parse_drive_server(options.server_url);
  if (!server) throw std::invalid_argument("remote drive: '" + options.server_url + "' is not http://host[:port]");
  if (!valid_robot_id(options.robot_id)) throw std::invalid_argument("remote drive: bad robot id");
  impl_->host = server->host;
  impl_->port = server->port;
  impl_->options = std::move(options);
  impl_->apply = std::move(apply);
  impl_->reconnect_at = Clock::now();
  impl_->on_tick();
  impl_->thread = std::thread([impl = impl_.get()] { impl->io.run(); });
}

RemoteDrive::~RemoteDrive() {
  asio::post(impl_->io, [impl = impl_.get()] {
    impl->quit = true;
    impl->tick.cancel();
    if (impl->ws) {
      beast::error_code ignored;
      beast::get_lowest_layer(*impl->ws).socket().close(ignored);
    }
  });
  impl_->thread.join();
  impl_->apply(0.0, 0.0);
}

bool RemoteDrive::connected() const {
  const std::lock_guard lock(impl_->mutex);
  return impl_->is_connected;
}

RemoteDriveStats RemoteDrive::stats() const {
  const std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

}  // namespace wm::robot
