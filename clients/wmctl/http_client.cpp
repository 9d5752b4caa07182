#include "clients/wmctl/http_client.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <string_view>

namespace wm::client {

namespace beast = boost::beast;
namespace http = boost::beast::http;
namespace net = boost::asio;

std::string map_target(const std::string& map, const std::string& target) {
  constexpr std::string_view api = "/api/v1/";
  if (map.empty() || map == "default" || !target.starts_with(api)) return target;
  const auto rest = std::string_view(target).substr(api.size());
  const auto first = rest.substr(0, rest.find_first_of("/?"));
  for (const std::string_view server_wide : {"network", "maps", "cluster"})
    if (first == server_wide) return target;
  return std::string(api) + "maps/" + map + "/" + std::string(rest);
}

HttpClient::HttpClient(const std::string& base_url, std::chrono::seconds timeout) : timeout_(timeout) {
  const std::string scheme = "http://";
  if (base_url.rfind(scheme, 0) != 0)
    throw ConnectionError("server URL must start with http:// (got '" + base_url + "')");
  std::string rest = base_url.substr(scheme.size());
  while (!rest.empty() && rest.back() == '/') rest.pop_back();
  if (rest.find('/') != std::string::npos)
    throw ConnectionError("server URL must not have a path (got '" + base_url + "')");
  const auto colon = rest.rfind(':');
  host_ = colon == std::string::npos ? rest : rest.substr(0, colon);
  port_ = colon == std::string::npos ? "80" : rest.substr(colon + 1);
  if (host_.empty() || port_.empty()) throw ConnectionError("bad server URL '" + base_url + "'");
}

HttpResult HttpClient::request(const std::string& method, const std::string& target, const std::string& body,
                               const std::string& content_type, const std::string& token) const {
  try {
    net::io_context ioc;
    net::ip::tcp::resolver resolver(ioc);
    beast::tcp_stream stream(ioc);
    stream.expires_after(timeout_);
    stream.connect(resolver.resolve(host_, port_));
    http::request<http::string_body> req{http::string_to_verb(method), map_target(map_, target), 11};
    req.set(http::field::host, host_);
    req.set(http::field::user_agent, "wmctl");
    if (!token.empty()) req.set(http::field::authorization, "Bearer " + token);
    if (!body.empty()) {
      req.set(http::field::content_type, content_type);
      req.body() = body;
    }
    req.prepare_payload();
    http::write(stream, req);
    beast::flat_buffer buffer;
    http::response_parser<http::string_body> parser;
    parser.body_limit(std::uint64_t{1} << 32);
    http::read(stream, buffer, parser);
    const auto& res = parser.get();
    beast::error_code ignored;
    stream.socket().shutdown(net::ip::tcp::socket::shutdown_both, ignored);
    return {static_cast<int>(res.result_int()), std::string(res[http::field::content_type]), res.body(),
            std::string(res[http::field::etag])};
  } catch (const boost::system::system_error& e) {
    throw ConnectionError("cannot reach the server at http://" + host_ + ":" + port_ + ": " + e.code().message());
  }
}

}  // namespace wm::client
