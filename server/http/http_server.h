#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "common/diagnostics.h"
#include "server/api/http_types.h"
#include "server/events/event_hub.h"
#include "server/http/websocket_endpoint.h"

namespace wm::http {

struct HttpOptions {
  std::string bind_address = "127.0.0.1";
  unsigned short port = 8080;             // 0 picks a free port; port() tells which
  std::size_t max_body_bytes = 16 << 20;  // larger bodies get 413 (explicit: Beast 1.74 rejects all with none)
  int threads = 4;                        // I/O threads: they only move bytes and never wait for a handler
  /// Threads that run read handlers, which may wait for the Prolog reader or serialise bodies of megabytes, at a
  /// lower CPU priority (nice +10), so serialising yields to the writers. Writes have their own threads, so readers
  /// cannot stop ingest.
  int handler_threads = 8;
  /// Threads that serve only writes. A write waits for the processing network to apply it, so each robot that posts
  /// at once holds one: with too few, requests queue here instead of reaching the store's group commit.
  int write_threads = 32;
  /// Requests of each lane (read, write) waiting for a handler thread; one more is answered 503 with
  /// Retry-After.
  std::size_t handler_queue = 256;
  std::chrono::seconds read_timeout{30};  // to receive a whole request, and to send a whole response
};

/// HTTP/1.1 server over Asio/Beast. Connection code only moves bytes: every complete request goes to
/// `handlers.handle`, on the I/O thread for Lane::immediate and on the handler pool otherwise (the answer
/// is written back on the connection's strand); oversized bodies (413), oversized headers (431),
/// unparsable requests (400) and a full handler queue (503, Retry-After: 1) are answered here with JSON
/// errors because they never reach a handler.
///
/// Accept errors (EMFILE/ENFILE when file descriptors run out, ...) are retried after a pause that starts
/// at 50 ms and doubles up to 1 s, logged once per streak, instead of re-arming at once (which spins a
/// core while the pending connection stays in the backlog).
class HttpServer {
 public:
  /// What the server does with a request. Each is called from several threads at once and must not throw.
  struct Handlers {
    /// Answers one complete request; may block (not for Lane::immediate).
    std::function<api::Response(const api::Request&)> handle;
    /// Where `handle` runs for this request (empty: Lane::read for every request).
    std::function<api::Lane(const api::Request&)> lane;
    /// Whether a WebSocket upgrade request names a WebSocket route (the api's route table says which); empty:
    /// none does, and every request goes to `handle`.
    std::function<bool(const api::Request&)> is_websocket;
    /// Refuses (the response) or allows (nullopt) a WebSocket upgrade of such a route (empty: allowed).
    std::function<std::optional<api::Response>(const api::Request&)> authorize_upgrade;
    /// Tried on the I/O thread before a read-lane request is queued: an answer that is ready at once (bytes
    /// already made), or nullopt to queue it. Must not block. Empty: every request is queued.
    std::function<std::optional<api::SharedResponse>(const api::Request&)> at_once;
    /// After authorize_upgrade allowed it: the endpoint that runs this WebSocket, or null for the live events (the
    /// `events` hub). Empty: every WebSocket is the events stream.
    std::function<std::shared_ptr<WebSocketEndpoint>(const api::Request&)> open_websocket;
    /// For the live events of one map of several: its hub, kept while the stream runs; null (or empty): `events`.
    std::function<std::shared_ptr<events::EventHub>(const api::Request&)> events_hub;
    /// For the live events of a map another node serves: the one message the stream sends after its hello (where the
    /// map is) before it closes; nullopt (or empty): none.
    std::function<std::optional<std::string>(const api::Request&)> events_elsewhere;
  };
  /// Binds and listens. WebSocket upgrades that `handlers.is_websocket` accepts run on the endpoint
  /// `handlers.open_websocket` gives, or else subscribe to `events` (when given). What the server recovers from (a
  /// failed accept, an endpoint that threw) goes to `diagnostics` (where "http"), which must outlive it.
  /// @throw boost::system::system_error when the address cannot be bound.
  HttpServer(const HttpOptions& options, Handlers handlers, common::Diagnostics& diagnostics,
             events::EventHub* events = nullptr);
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
