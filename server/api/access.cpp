#include "server/api/access.h"

#include <algorithm>
#include <boost/asio/ip/address.hpp>
#include <string>
#include <string_view>

#include "server/api/api_error.h"
#include "server/api/request.h"
#include "server/api/response.h"

namespace wm::api {
namespace {

namespace http = boost::beast::http;

std::string lower(std::string_view text) {
  std::string out(text);
  for (auto& c : out)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return out;
}

// The host of a Host header or an origin's authority, lower case, without port or trailing dot; IPv6 keeps its
// brackets ("[::1]").
std::string host_of_authority(std::string_view authority) {
  std::string host = lower(trimmed(authority));
  if (!host.empty() && host.front() == '[') {
    const auto close = host.find(']');
    return close == std::string::npos ? host : host.substr(0, close + 1);
  }
  host = host.substr(0, host.find(':'));
  if (!host.empty() && host.back() == '.') host.pop_back();
  return host;
}

bool is_ip_literal(const std::string& host) {
  std::string address = host;
  if (address.size() > 2 && address.front() == '[' && address.back() == ']') {
    address = address.substr(1, address.size() - 2);
  } else if (address.find(':') != std::string::npos) {
    return false;  // an IPv6 address in a Host header has brackets
  }
  boost::system::error_code ec;
  boost::asio::ip::make_address(address, ec);
  return !ec;
}

// Compares without stopping at the first difference, so the time taken says nothing about the token.
bool same_secret(std::string_view given, std::string_view expected) {
  unsigned char difference = given.size() == expected.size() ? 0 : 1;
  for (std::size_t i = 0; i < given.size(); ++i)
    difference |= static_cast<unsigned char>(given[i] ^ (expected.empty() ? 0 : expected[i % expected.size()]));
  return difference == 0;
}

// "Bearer <token>", the scheme in any case (RFC 7235 section 2.1), one or more spaces before the token.
bool bearer_matches(std::string_view authorization, std::string_view token) {
  constexpr std::string_view kScheme = "bearer";
  authorization = trimmed(authorization);
  if (authorization.size() <= kScheme.size() || lower(authorization.substr(0, kScheme.size())) != kScheme ||
      authorization[kScheme.size()] != ' ')
    return false;
  return same_secret(trimmed(authorization.substr(kScheme.size())), token);
}

}  // namespace

void require_allowed_host(const Request& request, const ApiOptions& options) {
  if (options.allowed_hosts.empty()) return;
  const auto value = header(request, http::field::host);
  if (trimmed(value).empty()) return;
  const auto host = host_of_authority(value);
  if (is_ip_literal(host)) return;
  if (std::find(options.allowed_hosts.begin(), options.allowed_hosts.end(), host) != options.allowed_hosts.end())
    return;
  throw ApiError(421, "misdirected_request",
                 "this server does not answer to Host '" + host +
                     "' (DNS rebinding?); start wmd with --allowed-hosts " + host + " to allow it");
}

void require_allowed_origin(const Request& request, const ApiOptions& options) {
  // A browser sends one Origin; with two, a check of the first would let the second decide elsewhere (a proxy, a
  // framework that reads the last one).
  if (request.count(http::field::origin) > 1)
    throw ApiError(403, "forbidden_origin", "a request with more than one Origin header is refused");
  const auto origin = lower(trimmed(header(request, http::field::origin)));
  if (origin.empty()) return;
  std::string normalised = origin;
  while (!normalised.empty() && normalised.back() == '/') normalised.pop_back();
  if (std::find(options.allowed_origins.begin(), options.allowed_origins.end(), normalised) !=
      options.allowed_origins.end())
    return;
  const auto scheme_end = normalised.find("://");
  const auto host = lower(trimmed(header(request, http::field::host)));
  if (scheme_end != std::string::npos && !host.empty()) {
    const auto scheme = normalised.substr(0, scheme_end);
    auto authority = normalised.substr(scheme_end + 3);
    // Browsers leave the default port out of Origin; a client may still write it in Host.
    const bool same = authority == host || (scheme == "http" && authority + ":80" == host) ||
                      (scheme == "https" && authority + ":443" == host);
    if ((scheme == "http" || scheme == "https") && same) return;
  }
  throw ApiError(403, "forbidden_origin",
                 "requests from pages of '" + origin +
                     "' are refused (not this server's origin); start wmd with --allowed-origins " + origin +
                     " to allow them");
}

void require_token(const Request& request, const ApiOptions& options) {
  if (options.token.empty()) return;
  if (!bearer_matches(header(request, http::field::authorization), options.token))
    throw ApiError(401, "unauthorized", "this server needs 'Authorization: Bearer <token>' to change state");
}

bool offers_subprotocol(const Request& request, std::string_view protocol) {
  bool offered = false;
  for_each_list_item(request, http::field::sec_websocket_protocol,
                     [&](std::string_view item) { offered = offered || item == protocol; });
  return offered;
}

std::optional<Response> authorize_upgrade(const Request& request, const ApiOptions& options) {
  try {
    require_allowed_host(request, options);
    require_allowed_origin(request, options);
    const auto& token = options.token;
    if (token.empty() || bearer_matches(header(request, http::field::authorization), token)) return std::nullopt;
    const auto raw = request.target();
    const auto given = parse_target(std::string_view(raw.data(), raw.size())).param("token");
    if (given && same_secret(*given, token)) return std::nullopt;
    throw ApiError(401, "unauthorized",
                   "the WebSockets of this server need 'Authorization: Bearer <token>' or ?token=<token>");
  } catch (const ApiError& e) {
    return error_response(request.version(), false, e.status(), e.error(), e.what());
  } catch (const std::exception& e) {
    return error_response(request.version(), false, 500, "internal_error", e.what());
  }
}

}  // namespace wm::api
