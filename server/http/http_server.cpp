#include "server/http/http_server.h"

#include <array>
#include <chrono>
#include <iostream>
#include <optional>
#include <thread>
#include <vector>

#include <boost/asio/dispatch.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <deque>

namespace wm::http {
namespace {

namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace websocket = boost::beast::websocket;

// One live-events WebSocket: forwards the hub's events in order; reads only to notice the close.
class EventSession : public std::enable_shared_from_this<EventSession> {
 public:
  EventSession(tcp::socket&& socket, events::EventHub& hub) : ws_(std::move(socket)), hub_(hub) {}
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
    for (auto& event : subscriber_->take()) outbox_.push_back(std::move(event));
    write_next();
  }

  void write_next() {
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
  events::EventHub& hub_;
  std::shared_ptr<events::EventHub::Subscriber> subscriber_;
  beast::flat_buffer buffer_;
  std::deque<std::string> outbox_;
  bool writing_ = false;
  bool stopped_ = false;
};

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket&& socket, const HttpOptions& options, const HttpServer::Handler& handler, events::EventHub* hub)
      : stream_(std::move(socket)), options_(options), handler_(handler), hub_(hub) {}

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
    if (websocket::is_upgrade(parser_->get())) {
      const auto target = parser_->get().target();
      if (hub_ && target.substr(0, target.find('?')) == "/api/v1/events") {
        stream_.expires_never();
        std::make_shared<EventSession>(stream_.release_socket(), *hub_)->run(parser_->release());
        return;
      }
    }
    write(handler_(parser_->get()));
  }

  void write(api::Response response) {
    response_ = std::make_shared<api::Response>(std::move(response));
    bhttp::async_write(stream_, *response_,
                       beast::bind_front_handler(&Session::on_write, shared_from_this(), response_->need_eof()));
  }

  void on_write(bool close_after, beast::error_code ec, std::size_t) {
    if (ec || close_after) return close();
    response_.reset();
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
  const HttpOptions& options_;
  const HttpServer::Handler& handler_;
  events::EventHub* hub_;
};

}  // namespace

struct HttpServer::Impl {
  HttpOptions options;
  Handler handler;
  events::EventHub* hub = nullptr;
  net::io_context ioc;
  tcp::acceptor acceptor{net::make_strand(ioc)};

  void accept() {
    acceptor.async_accept(net::make_strand(ioc), [this](beast::error_code ec, tcp::socket socket) {
      if (ec == net::error::operation_aborted) return;
      if (!ec) std::make_shared<Session>(std::move(socket), options, handler, hub)->start();
      if (acceptor.is_open()) accept();
    });
  }
};

HttpServer::HttpServer(const HttpOptions& options, Handler handler, events::EventHub* events)
    : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->handler = std::move(handler);
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
}

void HttpServer::stop() {
  net::post(impl_->acceptor.get_executor(), [this] {
    beast::error_code ignored;
    impl_->acceptor.close(ignored);
  });
  impl_->ioc.stop();
}

}  // namespace wm::http
