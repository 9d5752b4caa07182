#pragma once

#include <chrono>
#include <stdexcept>
#include <string>
#include <utility>

namespace wm::client {

/// The server could not be reached (refused, timed out, bad URL).
class ConnectionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct HttpResult {
  int status = 0;
  std::string content_type;
  std::string body;
  std::string etag;  // "" when the answer has none
};

/// `target` as one map's: a map's own resource "/api/v1/X..." becomes "/api/v1/maps/{map}/X..."; the server's own
/// (/api/v1/network, /api/v1/maps...), other paths, and every path for an empty map or "default"
/// stay as they are.
std::string map_target(const std::string& map, const std::string& target);

/// A minimal blocking HTTP/1.1 client for http://host:port URLs (one connection per request).
class HttpClient {
 public:
  /// @throw ConnectionError for a URL that is not http://host[:port][/].
  explicit HttpClient(const std::string& base_url, std::chrono::seconds timeout = std::chrono::seconds(60));
  /// Every request goes to map `map`'s resources (see map_target); empty: the default map's.
  void use_map(std::string map) { map_ = std::move(map); }
  /// @throw ConnectionError when the server cannot be reached.
  HttpResult request(const std::string& method, const std::string& target, const std::string& body = {},
                     const std::string& content_type = "application/json", const std::string& token = {}) const;

 private:
  std::string host_;
  std::string port_;
  std::chrono::seconds timeout_;
  std::string map_;
};

}  // namespace wm::client
