#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "server/api/router.h"
#include "server/events/event_hub.h"

namespace wm::http {

struct HttpOptions {
  std::string bind_address = "127.0.0.1";
  unsigned short port = 8080;            // 0 picks a free port; port() tells which
  std::size_t max_body_bytes = 16 << 20; // larger bodies get 413 (explicit: Beast 1.74 rejects all with none)
  int threads = 4;                       // I/O threads; handlers that write wait for the single writer
  std::chrono::seconds read_timeout{30};
};

/// HTTP/1.1 server over Asio/Beast. Connection code only moves bytes: every complete request goes to
/// `handler`; oversized bodies (413), oversized headers (431) and unparsable requests (400) are answered
/// here with JSON errors because they never become a request.
class HttpServer {
 public:
  using Handler = std::function<api::Response(const api::Request&)>;
  /// Binds and listens. WebSocket upgrades of GET /api/v1/events subscribe to `events` (when given).
  /// @throw boost::system::system_error when the address cannot be bound.
  HttpServer(const HttpOptions& options, Handler handler, events::EventHub* events = nullptr);
  ~HttpServer();
  unsigned short port() const;
  /// Serves until stop(); runs the I/O threads (the caller's thread is one of them).
  void run();
  /// Thread-safe; makes run() return.
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wm::http
