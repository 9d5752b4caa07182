#pragma once

#include <cstddef>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>

#include "server/api/http_types.h"
#include "server/api/map_cache.h"

namespace wm::api {

/// A 200 (or `status`) JSON answer, not cached. Text that was not checked as UTF-8 on its way in is written
/// with U+FFFD rather than failing the request after the work is done (nlohmann's type_error 316).
/// @throw ApiError(422, "answer_too_large") when the text is longer than `max_bytes`.
Response json_response(const Request& request, const nlohmann::json& body,
                       boost::beast::http::status status = boost::beast::http::status::ok,
                       std::size_t max_bytes = std::numeric_limits<std::size_t>::max());

/// A 200 answer of `body` as is, with its Content-Type.
Response raw_response(const Request& request, std::string body, const std::string& content_type);

/// An answer whose bytes stay the same for `tag` (an entity tag without quotes, e.g. "<instance>-v12"): 304 Not
/// Modified when If-None-Match names it (in either coding), the gzip form when Accept-Encoding allows it (tagged
/// "<tag>-gzip", as RFC 9110 wants a coding to have its own tag), and Cache-Control: no-cache (a copy may be kept
/// but must be revalidated: the map changes at any time).
/// `may_gzip` false: never compressed (binary tiles, made for each request, would be compressed again each time).
Response tagged_response(const Request& request, const std::shared_ptr<const MapBody>& body, const std::string& tag,
                         bool may_gzip = true);

/// The same answer made on an I/O thread: nullopt when it needs a gzip form not made yet (compressing is not for that
/// thread); otherwise the body's bytes are handed out in `shared_body` instead of being copied into the response
/// (which then carries the headers, its Content-Length included).
std::optional<Response> tagged_response_at_once(const Request& request, const std::shared_ptr<const MapBody>& body,
                                                const std::string& tag,
                                                std::shared_ptr<const std::string>& shared_body);

/// Whether Accept-Encoding allows gzip (named or "*", with a q-value above 0).
bool accepts_gzip(const Request& request);

/// `response` as the answer to `request`: for HEAD the same headers, Content-Length included, without the body
/// (RFC 9110 9.3.2: a client reads no content after them, so bytes sent would be taken for the next answer).
Response for_request_method(const Request& request, Response response);

/// The JSON error {"error", "detail"} with its status (also used by the connection code for 413, 431, 503).
Response error_response(unsigned http_version, bool keep_alive, int status, const std::string& error,
                        const std::string& detail);

}  // namespace wm::api
