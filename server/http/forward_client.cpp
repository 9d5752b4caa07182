#include "server/http/forward_client.h"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/write.hpp>
#include <limits>
#include <regex>

namespace wm::http {

namespace beast = boost::beast;
namespace bhttp = boost::beast::http;

std::optional<NodeAddress> parse_node_url(const std::string& url) {
  static const std::regex url_form(R"(http://([^/:]+|\[[^\]]+\]):(\d{1,5})/?)");
  std::smatch parts;
  if (!std::regex_match(url, parts, url_form)) return std::nullopt;
  return NodeAddress{parts[1].str(), parts[2].str()};
}

api::Response forward_request(api::Request request, const std::string& base_url, std::chrono::milliseconds timeout,
                              const std::function<bool()>& still_worth_it, std::chrono::milliseconds check_every) {
  const auto address = parse_node_url(base_url);
  if (!address) throw ForwardError("not a node URL: '" + base_url + "'");
  const auto& port = address->port;
  auto host = address->host;
  if (host.size() > 2 && host.front() == '[') host = host.substr(1, host.size() - 2);
  try {
    // Asynchronous steps on an io_context of its own: the stream's deadline applies only to those, and a node that
    // is paused (SIGSTOP) accepts the connection and then says nothing.
    boost::asio::io_context io;
    beast::tcp_stream stream(io);
    boost::asio::ip::tcp::resolver resolver(io);
    const auto endpoints = resolver.resolve(host, port);
    request.set(bhttp::field::host, address->host + ":" + port);
    request.keep_alive(false);
    request.prepare_payload();
    beast::flat_buffer buffer;
    bhttp::response_parser<bhttp::string_body> parser;
    parser.body_limit(std::numeric_limits<std::uint64_t>::max());  // the other node limits what it sends
    beast::error_code failure;
    stream.expires_after(timeout);
    stream.async_connect(endpoints, [&](beast::error_code ec, const auto&) {
      if (ec) return void(failure = ec);
      bhttp::async_write(stream, request, [&](beast::error_code ec, std::size_t) {
        if (ec) return void(failure = ec);
        bhttp::async_read(stream, buffer, parser, [&](beast::error_code ec, std::size_t) { failure = ec; });
      });
    });
    bool done = false;
    while (!done) {
      io.run_for(check_every);
      done = io.stopped();
      if (!done && still_worth_it && !still_worth_it()) {
        beast::error_code ignored;
        stream.socket().close(ignored);
        throw ForwardError("gave up waiting for the node at " + base_url + ": it no longer serves the map");
      }
    }
    if (failure) throw boost::system::system_error(failure);
    beast::error_code ignored;
    stream.socket().shutdown(boost::asio::ip::tcp::socket::shutdown_both, ignored);
    auto response = parser.release();
    response.erase(bhttp::field::connection);
    response.erase("Keep-Alive");
    return response;
  } catch (const boost::system::system_error& e) {
    throw ForwardError("the node at " + base_url + " did not answer: " + e.code().message());
  }
}

}  // namespace wm::http
