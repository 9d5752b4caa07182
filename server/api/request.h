#pragma once

// Reading a request: its target, query parameters, headers and JSON body. Every refusal is an ApiError (400 or 415)
// naming what is wrong.
#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "server/api/http_types.h"

namespace wm::api {

/// A request target, percent-decoded: the path, and the query parameters by name (the last of a repeated name).
struct Target {
  std::string path;
  std::map<std::string, std::string> query;

  /// The parameter's value, nullopt when absent.
  std::optional<std::string> param(const std::string& name) const;
};

/// Parses a request target. Query parameters become names (?name=, ?level=) that end up in JSON: each must be
/// UTF-8. @throw ApiError(400) for bad percent-encoding or text that is not UTF-8.
Target parse_target(std::string_view target);

/// The value of `field`, empty when absent.
std::string_view header(const Request& request, boost::beast::http::field field);
/// `text` without the optional whitespace (spaces, tabs) around it, as header values carry it (RFC 9110 5.6.3).
std::string_view trimmed(std::string_view text);
/// ASCII case-insensitive equality, as header tokens compare.
bool iequals(std::string_view a, std::string_view b);
/// Calls `each` with every `separator`-separated part of `text`, trimmed.
template <typename F>
void for_each_part(std::string_view text, char separator, F&& each) {
  for (;;) {
    const auto end = text.find(separator);
    each(trimmed(text.substr(0, end)));
    if (end == std::string_view::npos) return;
    text.remove_prefix(end + 1);
  }
}
/// Calls `each` with every item of a comma-separated header list (RFC 9110 5.6.1), over every line of the header.
template <typename F>
void for_each_list_item(const Request& request, boost::beast::http::field field, F&& each) {
  const auto [first, last] = request.equal_range(field);
  for (auto it = first; it != last; ++it)
    for_each_part(std::string_view(it->value().data(), it->value().size()), ',', each);
}
/// Whether the Content-Type (without parameters, case-insensitive) is `wanted`.
bool has_content_type(const Request& request, std::string_view wanted);

/// An integer query parameter in [min, max], `fallback` when absent. @throw ApiError(400) naming it.
std::int64_t query_int(const Target& target, const std::string& key, std::int64_t fallback, std::int64_t min,
                       std::int64_t max);

/// A box in metres, as the query parameter bbox=x0,y0,x1,y1 gives it.
struct QueryBox {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};
/// The bbox parameter, nullopt when absent. @throw ApiError(400, bbox) unless it is four finite numbers of at most
/// 10⁶ m with x1 > x0 and y1 > y0.
std::optional<QueryBox> query_bbox(const Target& target);

/// How old a map the client accepts: Cache-Control: max-stale=N (seconds, RFC 9111 5.2.1.2); a bare max-stale ("any
/// age") counts as 60 s. Zero without the directive or with a malformed value (then the answer is simply fresh).
std::chrono::milliseconds accepted_staleness(const Request& request);

/// @throw ApiError 400 for an empty body, 415 when it is not sent as application/json.
void require_json_body(const Request& request);
/// The body as a JSON object (after require_json_body). @throw ApiError(400), json_codec::CodecError.
nlohmann::json parse_json_object(const Request& request);
/// A string field of 1 to max_size characters. @throw ApiError(400) naming it.
std::string string_field(const nlohmann::json& doc, const std::string& key, std::size_t max_size);
/// An integer field in [1, max], `fallback` when absent. @throw ApiError(400) naming it.
std::size_t count_field(const nlohmann::json& doc, const std::string& key, std::size_t fallback, std::size_t max);
/// @throw ApiError(400) naming the first key of `doc` that is not `known`.
void require_known_keys(const nlohmann::json& doc, std::initializer_list<std::string_view> known);

/// The client's request id: the Idempotency-Key header, 1 to 200 visible ASCII characters other than '"' and
/// '\', bare or in double quotes (the structured-field string form of the IETF httpapi draft). nullopt without
/// the header. @throw ApiError(400, Idempotency-Key) for a malformed id.
std::optional<std::string> request_id(const Request& request);

}  // namespace wm::api
