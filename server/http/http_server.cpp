#include "server/http/http_server.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <boost/asio/dispatch.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "server/api/response.h"

namespace wm::http {
namespace {

namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace websocket = boost::beast::websocket;

// Threads that take jobs from one bounded queue, in order. A full queue refuses at once (the caller answers
// 503) rather than letting requests pile up without bound.
class WorkQueue {
 public:
  /// `nice`: added to the threads' CPU niceness (Linux schedules threads on their own; 0 leaves it).
  WorkQueue(int threads, std::size_t max_queued, int nice) : max_queued_(max_queued) {
    for (int i = 0; i < threads; ++i)
      threads_.emplace_back([this, nice] {
        if (nice != 0) ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), nice);  // best effort
        loop();
      });
  }
  ~WorkQueue() { stop(); }
  WorkQueue(const WorkQueue&) = delete;
  WorkQueue& operator=(const WorkQueue&) = delete;

  /// False when the queue is full or stopped.
  bool try_post(std::function<void()> job) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_ || queue_.size() >= max_queued_) return false;
      queue_.push_back(std::move(job));
    }
    cv_.notify_one();
    return true;
  }

  /// Lets running jobs finish, drops queued ones, joins. Idempotent.
  void stop() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    cv_.notify_all();
    for (auto& t : threads_)
      if (t.joinable()) t.join();
    std::deque<std::function<void()>> dropped;
    std::lock_guard lock(mutex_);
    dropped.swap(queue_);
  }

 private:
  void loop() {
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock lock(mutex_);
        cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
        if (stopping_) return;
        job = std::move(queue_.front());
        queue_.pop_front();
      }
      job();
    }
  }

  const std::size_t max_queued_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

// The handler threads in two lanes. Writes (ingest, plan loads, reloads) mostly wait for the processing network
// and have threads of their own, so readers can never take every thread.
// Reads (map, grid, queries, dry runs) get the rest, at a lower CPU priority: on a busy machine the
// serialisation of megabytes of map and grid yields to the writer instead of slowing ingest (on this
// 2-core VM, 8 map and 4 grid readers took ingest from 118 to 12 scans/s at equal priority).
class HandlerPool {
 public:
  static constexpr int kReadNice = 10;

  HandlerPool(int read_threads, int write_threads, std::size_t max_queued)
      : writes_(std::max(1, write_threads), max_queued, 0), reads_(std::max(1, read_threads), max_queued, kReadNice) {}

  bool try_post(bool write, std::function<void()> job) { return (write ? writes_ : reads_).try_post(std::move(job)); }
  void stop() {
    reads_.stop();
    writes_.stop();
  }

 private:
  WorkQueue writes_;
  WorkQueue reads_;
};

// One live-events WebSocket: forwards the hub's events in order; reads only to notice the close.
class EventSession : public std::enable_shared_from_this<EventSession> {
 public:
  /// `farewell`: sent after the hello, and then the stream closes (a map another node serves: where it is).
  EventSession(tcp::socket&& socket, events::EventHub& hub, std::shared_ptr<events::EventHub> owner = nullptr,
               std::string farewell = {})
      : ws_(std::move(socket)), owner_(std::move(owner)), hub_(hub), farewell_(std::move(farewell)) {}
  ~EventSession() {
    if (subscriber_) hub_.unsubscribe(subscriber_);
  }

  void run(bhttp::request<bhttp::string_body> request) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.async_accept(request, beast::bind_front_handler(&EventSession::on_accept, shared_from_this()));
  }

 private:
  void on_accept(beast::error_code ec) {
    if (ec) return;
    std::weak_ptr<EventSession> weak = weak_from_this();
    subscriber_ = hub_.subscribe([weak] {
      if (auto self = weak.lock()) net::post(self->ws_.get_executor(), [self] { self->pump(); });
    });
    outbox_.push_back(R"({"type":"hello","api":"/api/v1"})");
    if (!farewell_.empty()) {
      outbox_.push_back(std::move(farewell_));
      closing_ = true;
    }
    write_next();
    read();
  }

  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return self->stop();
      self->buffer_.consume(self->buffer_.size());  // clients have nothing to say here
      self->read();
    });
  }

  void pump() {
    if (writing_ || stopped_) return;
    if (!closing_) {
      for (auto& event : subscriber_->take()) {
        outbox_.push_back(std::move(event.json));
        // The map moved to another node: its last word, then the stream ends (the client follows "owner").
        if (event.kind == events::EventKind::map_moved) {
          closing_ = true;
          break;
        }
      }
    }
    write_next();
  }

  void write_next() {
    if (outbox_.empty() && closing_ && !stopped_) {
      stopped_ = true;
      writing_ = true;
      return ws_.async_close(websocket::close_reason(websocket::close_code::try_again_later),
                             [self = shared_from_this()](beast::error_code) { self->stop(); });
    }
    if (outbox_.empty() || stopped_) {
      writing_ = false;
      return;
    }
    writing_ = true;
    ws_.text(true);
    ws_.async_write(net::buffer(outbox_.front()), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return self->stop();
      self->outbox_.pop_front();
      self->writing_ = false;
      if (self->outbox_.empty()) {
        self->pump();
      } else {
        self->write_next();
      }
    });
  }

  void stop() {
    stopped_ = true;
    if (subscriber_) {
      hub_.unsubscribe(subscriber_);
      subscriber_.reset();
    }
  }

  websocket::stream<beast::tcp_stream> ws_;
  std::shared_ptr<events::EventHub> owner_;  // keeps a map's hub while the stream runs (null: the server's)
  events::EventHub& hub_;
  std::shared_ptr<events::EventHub::Subscriber> subscriber_;
  beast::flat_buffer buffer_;
  std::deque<std::string> outbox_;
  std::string farewell_;
  bool writing_ = false;
  bool stopped_ = false;
  bool closing_ = false;  // the last message is queued: close once the outbox is empty
};

// A WebSocket run by an endpoint of the api's choosing (the Foxglove bridge): moves whole messages both ways and
// leaves their meaning to the endpoint. One write at a time; the endpoint's queue is taken only when the last batch is
// written, so a client that reads slowly leaves its messages in the endpoint's bounded queue, not here.
class EndpointSession : public std::enable_shared_from_this<EndpointSession> {
 public:
  // Client messages are small JSON (subscriptions); anything larger is refused by Beast (the connection fails).
  static constexpr std::size_t kMaxClientMessageBytes = 1 << 20;
  // Pinged after half of this without a word from the client, dropped after all of it: a client that stopped reading
  // (it cannot answer a ping) does not hold its connection for ever. Generous, because Beast counts only what the
  // client sends, and its ping waits behind a message being written: 2 minutes lets a client on a slow link take
  // a grid of tens of megabytes.
  static constexpr std::chrono::seconds kIdleTimeout{120};

  EndpointSession(tcp::socket&& socket, std::shared_ptr<WebSocketEndpoint> endpoint, common::Diagnostics& diagnostics)
      : ws_(std::move(socket)), endpoint_(std::move(endpoint)), diagnostics_(diagnostics) {}
  ~EndpointSession() { stop(); }

  void run(bhttp::request<bhttp::string_body> request) {
    auto timeouts = websocket::stream_base::timeout::suggested(beast::role_type::server);
    timeouts.idle_timeout = kIdleTimeout;
    timeouts.keep_alive_pings = true;
    ws_.set_option(timeouts);
    ws_.read_message_max(kMaxClientMessageBytes);
    if (const auto protocol = endpoint_->subprotocol(); !protocol.empty()) {
      ws_.set_option(websocket::stream_base::decorator([protocol = std::string(protocol)](websocket::response_type& r) {
        r.set(bhttp::field::sec_websocket_protocol, protocol);
      }));
    }
    ws_.async_accept(request, beast::bind_front_handler(&EndpointSession::on_accept, shared_from_this()));
  }

 private:
  void on_accept(beast::error_code ec) {
    if (ec) return stop();
    std::weak_ptr<EndpointSession> weak = weak_from_this();
    opened_ = true;
    try {  // endpoints do not throw; should one (bad_alloc), its connection ends rather than the I/O thread
      // The wake comes from the endpoint's thread (a Foxglove bridge's). The strong reference it takes moves into
      // the posted handler, so the session's last reference is never let go on that thread: the session owns the
      // endpoint, which may own that very thread (a map's bridge), and a thread cannot join itself.
      endpoint_->open([weak] {
        if (auto self = weak.lock()) {
          auto executor = self->ws_.get_executor();
          net::post(executor, [self = std::move(self)] { self->pump(); });
        }
      });
    } catch (const std::exception& e) {
      diagnostics_.report(common::Severity::warning, "http", std::string("WebSocket not opened: ") + e.what());
      return stop();
    }
    pump();
    read();
  }

  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec || self->stopped_) return self->stop();
      const auto data = self->buffer_.cdata();
      try {
        self->endpoint_->receive(std::string_view(static_cast<const char*>(data.data()), data.size()),
                                 !self->ws_.got_text());
      } catch (const std::exception& e) {  // endpoints do not throw; should one, its connection ends
        self->diagnostics_.report(common::Severity::warning, "http", std::string("WebSocket closed: ") + e.what());
        return self->close_now();
      }
      self->buffer_.consume(self->buffer_.size());
      self->read();
    });
  }

  void pump() {
    if (writing_ || stopped_) return;
    try {
      for (auto& frame : endpoint_->take()) outbox_.push_back(std::move(frame));
    } catch (const std::exception& e) {
      diagnostics_.report(common::Severity::warning, "http", std::string("WebSocket closed: ") + e.what());
      return close_now();
    }
    write_next();
  }

  void close_now() {
    stop();
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().close(ignored);
  }

  void write_next() {
    if (outbox_.empty() || stopped_) {
      writing_ = false;
      return;
    }
    writing_ = true;
    const auto& frame = outbox_.front();
    ws_.binary(frame.binary);
    buffers_ = {net::buffer(frame.head), frame.body ? net::buffer(*frame.body) : net::const_buffer{}};
    ws_.async_write(buffers_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return self->stop();
      const bool last = self->outbox_.front().close_after;
      self->outbox_.pop_front();
      self->writing_ = false;
      if (last) {  // the endpoint said its last word (a refusal): close, then the read ends with the connection
        self->stop();
        return self->ws_.async_close(websocket::close_reason(websocket::close_code::try_again_later),
                                     [self](beast::error_code) {});
      }
      if (self->outbox_.empty()) {
        self->pump();
      } else {
        self->write_next();
      }
    });
  }

  // The outbox stays until the session goes: a write in flight still reads its front frame.
  void stop() {
    if (stopped_) return;
    stopped_ = true;
    if (opened_) endpoint_->close();
  }

  websocket::stream<beast::tcp_stream> ws_;
  std::shared_ptr<WebSocketEndpoint> endpoint_;
  common::Diagnostics& diagnostics_;
  beast::flat_buffer buffer_;
  std::deque<WebSocketFrame> outbox_;
  std::array<net::const_buffer, 2> buffers_;
  bool opened_ = false;
  bool writing_ = false;
  bool stopped_ = false;
};

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket&& socket, const HttpOptions& options, const HttpServer::Handlers& handlers, HandlerPool& pool,
          events::EventHub* hub, common::Diagnostics& diagnostics)
      : stream_(std::move(socket)),
        options_(options),
        handlers_(handlers),
        pool_(pool),
        hub_(hub),
        diagnostics_(diagnostics) {}

  void start() { net::dispatch(stream_.get_executor(), beast::bind_front_handler(&Session::read, shared_from_this())); }

 private:
  void read() {
    parser_.emplace();
    parser_->body_limit(options_.max_body_bytes);
    stream_.expires_after(options_.read_timeout);
    bhttp::async_read(stream_, buffer_, *parser_, beast::bind_front_handler(&Session::on_read, shared_from_this()));
  }

  void on_read(beast::error_code ec, std::size_t) {
    if (ec == bhttp::error::end_of_stream || ec == beast::error::timeout || ec == net::error::operation_aborted ||
        ec == net::error::connection_reset || ec == net::error::eof) {
      return close();
    }
    if (ec) {
      // The request never became whole: answer, then close (the stream position is unknown).
      int status = 400;
      std::string error = "bad_request";
      std::string detail = "malformed HTTP request: " + ec.message();
      if (ec == bhttp::error::body_limit) {
        status = 413;
        error = "payload_too_large";
        detail = "body larger than " + std::to_string(options_.max_body_bytes) + " bytes";
      } else if (ec == bhttp::error::header_limit) {
        status = 431;
        error = "headers_too_large";
        detail = "request headers too large";
      }
      return write(api::error_response(11, false, status, error, detail));
    }
    if ((hub_ || handlers_.open_websocket) && websocket::is_upgrade(parser_->get()) && handlers_.is_websocket &&
        handlers_.is_websocket(parser_->get())) {
      if (handlers_.authorize_upgrade) {
        if (auto refusal = handlers_.authorize_upgrade(parser_->get())) return write(std::move(*refusal));
      }
      auto endpoint = handlers_.open_websocket ? handlers_.open_websocket(parser_->get()) : nullptr;
      auto map_hub = !endpoint && handlers_.events_hub ? handlers_.events_hub(parser_->get()) : nullptr;
      auto farewell = !endpoint && !map_hub && handlers_.events_elsewhere ? handlers_.events_elsewhere(parser_->get())
                                                                          : std::nullopt;
      if (farewell && hub_) {
        stream_.expires_never();
        std::make_shared<EventSession>(stream_.release_socket(), *hub_, nullptr, std::move(*farewell))
            ->run(parser_->release());
        return;
      }
      if (endpoint || map_hub || hub_) {
        stream_.expires_never();
        if (endpoint) {
          std::make_shared<EndpointSession>(stream_.release_socket(), std::move(endpoint), diagnostics_)
              ->run(parser_->release());
        } else {
          auto& hub = map_hub ? *map_hub : *hub_;
          std::make_shared<EventSession>(stream_.release_socket(), hub, std::move(map_hub))->run(parser_->release());
        }
        return;
      }
    }
    const auto lane = handlers_.lane ? handlers_.lane(parser_->get()) : api::Lane::read;
    if (lane == api::Lane::immediate) return write(answer(parser_->get()));
    // Bytes already made (the map of the current version, a 304) need no handler thread: served here, they skip
    // the queue and the handlers' lower CPU priority, which under ingest is most of their latency.
    if (lane == api::Lane::read && handlers_.at_once) {
      if (auto ready = handlers_.at_once(parser_->get())) return write_shared(std::move(*ready));
    }
    // The handler may wait for the writer or Prolog for long: the I/O thread goes back to other connections,
    // and the answer comes back to this connection's strand.
    auto request = std::make_shared<api::Request>(parser_->release());
    stream_.expires_never();
    const auto version = request->version();
    const bool keep_alive = request->keep_alive();
    const bool queued = pool_.try_post(lane == api::Lane::write, [self = shared_from_this(), request] {
      auto response = self->answer(*request);
      net::post(self->stream_.get_executor(),
                [self, response = std::move(response)]() mutable { self->write(std::move(response)); });
    });
    if (!queued) {
      auto busy = api::error_response(version, keep_alive, 503, "busy",
                                      "every request handler is taken and the queue is full; retry later");
      busy.set(bhttp::field::retry_after, "1");
      write(api::for_request_method(*request, std::move(busy)));
    }
  }

  api::Response answer(const api::Request& request) const {
    try {
      return handlers_.handle(request);
    } catch (const std::exception& e) {  // handlers do not throw; should one, the client still gets an answer
      return api::for_request_method(request,
                                     api::error_response(request.version(), false, 500, "internal_error", e.what()));
    }
  }

  void write(api::Response response) {
    stream_.expires_after(options_.read_timeout);
    response_ = std::make_shared<api::Response>(std::move(response));
    bhttp::async_write(stream_, *response_,
                       beast::bind_front_handler(&Session::on_write, shared_from_this(), response_->need_eof()));
  }

  // The same for an answer whose body is shared with the map cache: no copy of the bytes.
  void write_shared(api::SharedResponse response) {
    stream_.expires_after(options_.read_timeout);
    shared_response_ = std::make_shared<api::SharedResponse>(std::move(response));
    bhttp::async_write(stream_, *shared_response_,
                       beast::bind_front_handler(&Session::on_write, shared_from_this(), shared_response_->need_eof()));
  }

  void on_write(bool close_after, beast::error_code ec, std::size_t) {
    if (ec || close_after) return close();
    response_.reset();
    shared_response_.reset();
    read();
  }

  void close() {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
    // Lingering close: read and discard what the client still sends (the rest of an oversized body)
    // so that closing does not reset the connection before the client has read our answer.
    stream_.expires_after(std::chrono::seconds(5));
    drain();
  }

  void drain() {
    stream_.async_read_some(net::buffer(discard_), [self = shared_from_this()](beast::error_code ec, std::size_t n) {
      self->drained_bytes_ += n;
      if (ec || self->drained_bytes_ > kMaxDrainBytes) {
        beast::error_code ignored;
        self->stream_.socket().close(ignored);
        return;
      }
      self->drain();
    });
  }

  static constexpr std::size_t kMaxDrainBytes = std::size_t{256} << 20;
  std::array<char, 64 * 1024> discard_{};
  std::size_t drained_bytes_ = 0;

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<bhttp::request_parser<bhttp::string_body>> parser_;
  std::shared_ptr<api::Response> response_;
  std::shared_ptr<api::SharedResponse> shared_response_;
  const HttpOptions& options_;
  const HttpServer::Handlers& handlers_;
  HandlerPool& pool_;
  events::EventHub* hub_;
  common::Diagnostics& diagnostics_;
};

}  // namespace

struct HttpServer::Impl {
  Impl(const HttpOptions& o, common::Diagnostics& d)
      : options(o), diagnostics(d), pool(o.handler_threads, o.write_threads, o.handler_queue) {}

  const HttpOptions options;
  common::Diagnostics& diagnostics;
  Handlers handlers;
  events::EventHub* hub = nullptr;
  net::io_context ioc;
  tcp::acceptor acceptor{net::make_strand(ioc)};
  net::steady_timer accept_timer{acceptor.get_executor()};
  std::chrono::milliseconds accept_delay{0};  // 0: the last accept succeeded
  // Declared after the io_context: destroyed (joined) first, and queued jobs' sessions still find it.
  HandlerPool pool;

  void accept() {
    acceptor.async_accept(net::make_strand(ioc), [this](beast::error_code ec, tcp::socket socket) {
      if (ec == net::error::operation_aborted || !acceptor.is_open()) return;
      if (ec) return back_off(ec);
      if (accept_delay.count() != 0) {
        diagnostics.report(common::Severity::info, "http", "accepting connections again");
        accept_delay = std::chrono::milliseconds(0);
      }
      std::make_shared<Session>(std::move(socket), options, handlers, pool, hub, diagnostics)->start();
      accept();
    });
  }

  // EMFILE, ENFILE, ENOBUFS...: the pending connection stays in the backlog, so accepting again at once
  // fails again at once. Wait 50 ms, doubling up to 1 s, until descriptors are free again.
  void back_off(const beast::error_code& ec) {
    if (accept_delay.count() == 0)
      diagnostics.report(common::Severity::warning, "http",
                         "accept failed (" + ec.message() + "); retrying every 50 ms to 1 s until it succeeds");
    accept_delay = std::clamp(accept_delay * 2, std::chrono::milliseconds(50), std::chrono::milliseconds(1000));
    accept_timer.expires_after(accept_delay);
    accept_timer.async_wait([this](beast::error_code wait_ec) {
      if (!wait_ec && acceptor.is_open()) accept();
    });
  }
};

HttpServer::HttpServer(const HttpOptions& options, Handlers handlers, common::Diagnostics& diagnostics,
                       events::EventHub* events)
    : impl_(std::make_unique<Impl>(options, diagnostics)) {
  impl_->handlers = std::move(handlers);
  impl_->hub = events;
  const tcp::endpoint endpoint{net::ip::make_address(options.bind_address), options.port};
  impl_->acceptor.open(endpoint.protocol());
  impl_->acceptor.set_option(net::socket_base::reuse_address(true));
  impl_->acceptor.bind(endpoint);
  impl_->acceptor.listen(net::socket_base::max_listen_connections);
}

HttpServer::~HttpServer() = default;

unsigned short HttpServer::port() const { return impl_->acceptor.local_endpoint().port(); }

void HttpServer::run() {
  impl_->accept();
  std::vector<std::thread> threads;
  for (int i = 1; i < impl_->options.threads; ++i) threads.emplace_back([this] { impl_->ioc.run(); });
  impl_->ioc.run();
  for (auto& t : threads) t.join();
  impl_->pool.stop();  // handlers still running finish (their answers go nowhere); queued ones are dropped
}

void HttpServer::stop() {
  net::post(impl_->acceptor.get_executor(), [this] {
    beast::error_code ignored;
    impl_->acceptor.close(ignored);
    impl_->accept_timer.cancel();
  });
  impl_->ioc.stop();
}

}  // namespace wm::http
