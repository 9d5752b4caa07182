#include "server/api/response.h"

#include <string_view>

#include "server/api/api_error.h"
#include "server/api/request.h"

namespace wm::api {

namespace http = boost::beast::http;
using nlohmann::json;

Response json_response(const Request& request, const json& body, http::status status, std::size_t max_bytes) {
  Response res{status, request.version()};
  res.set(http::field::content_type, "application/json");
  res.set(http::field::cache_control, "no-store");
  res.keep_alive(request.keep_alive());
  res.body() = body.dump(-1, ' ', false, json::error_handler_t::replace);
  if (res.body().size() > max_bytes)
    throw ApiError(422, "answer_too_large",
                   "the answer is " + std::to_string(res.body().size()) + " bytes, more than the " +
                       std::to_string(max_bytes) + " this server sends; ask for less");
  res.prepare_payload();
  return res;
}

Response raw_response(const Request& request, std::string body, const std::string& content_type) {
  Response res{http::status::ok, request.version()};
  res.set(http::field::content_type, content_type);
  res.keep_alive(request.keep_alive());
  res.body() = std::move(body);
  res.prepare_payload();
  return res;
}

namespace {

// The tag of `identity` or `gzip` that If-None-Match (every line of it) names, "" when none. Weak comparison
// (RFC 9110 13.1.2): W/ is ignored; "*" names the one being sent.
std::string none_match_tag(const Request& request, const std::string& identity, const std::string& gzip,
                           const std::string& sending) {
  std::string found;
  for_each_list_item(request, http::field::if_none_match, [&](std::string_view tag) {
    if (tag == "*") found = sending;
    if (tag.substr(0, 2) == "W/") tag.remove_prefix(2);
    if (tag == identity || tag == gzip) found = std::string(tag);
  });
  return found;
}

}  // namespace

bool accepts_gzip(const Request& request) {
  bool gzip = false, refused = false;
  for_each_list_item(request, http::field::accept_encoding, [&](std::string_view item) {
    const auto semicolon = item.find(';');
    const auto coding = trimmed(item.substr(0, semicolon));
    bool zero = false;  // "q=0" (or 0.0, 0.000) among the parameters refuses the coding
    if (semicolon != std::string_view::npos) {
      for_each_part(item.substr(semicolon + 1), ';', [&](std::string_view param) {
        if (param.size() >= 2 && (param[0] == 'q' || param[0] == 'Q') && param[1] == '=') {
          const auto q = trimmed(param.substr(2));
          zero = !q.empty() && q.find_first_not_of("0.") == std::string_view::npos;
        }
      });
    }
    if (iequals(coding, "gzip") || iequals(coding, "x-gzip")) (zero ? refused : gzip) = true;
    if (coding == "*" && !zero) gzip = true;
  });
  return gzip && !refused;
}

namespace {

// tagged_response, and with `share_into` its at-once form (nullopt: a gzip form not made yet).
std::optional<Response> tagged(const Request& request, const std::shared_ptr<const MapBody>& shared,
                               const std::string& tag, bool may_gzip, std::shared_ptr<const std::string>* share_into) {
  const MapBody& body = *shared;
  const std::string identity = "\"" + tag + "\"", gzip_tag = "\"" + tag + "-gzip\"";
  // Small bodies are not worth a compression step.
  const bool gzip = may_gzip && body.bytes.size() >= 1024 && accepts_gzip(request);
  Response res{http::status::ok, request.version()};
  res.set(http::field::cache_control, "no-cache");
  res.set(http::field::vary, "Accept-Encoding");
  res.set(http::field::etag, gzip ? gzip_tag : identity);
  res.keep_alive(request.keep_alive());
  if (const auto matched = none_match_tag(request, identity, gzip_tag, gzip ? gzip_tag : identity); !matched.empty()) {
    res.result(http::status::not_modified);
    res.set(http::field::etag, matched);  // the copy the client holds is still good
    return res;                           // no body, no Content-Length of the 200's
  }
  res.set(http::field::content_type, body.content_type);
  std::shared_ptr<const std::string> bytes(shared, &body.bytes);  // shares the cached body's ownership
  if (gzip) {
    bytes = share_into ? MapCache::gzip_if_made(body) : MapCache::gzip_of(body);
    if (!bytes) return std::nullopt;
    res.set(http::field::content_encoding, "gzip");
  }
  if (share_into) {
    res.content_length(bytes->size());
    *share_into = std::move(bytes);
    return res;
  }
  res.body() = *bytes;
  res.prepare_payload();
  return res;
}

}  // namespace

Response tagged_response(const Request& request, const std::shared_ptr<const MapBody>& body, const std::string& tag,
                         bool may_gzip) {
  return *tagged(request, body, tag, may_gzip, nullptr);  // gzip_of makes the form it lacks: never nullopt
}

std::optional<Response> tagged_response_at_once(const Request& request, const std::shared_ptr<const MapBody>& body,
                                                const std::string& tag,
                                                std::shared_ptr<const std::string>& shared_body) {
  return tagged(request, body, tag, /*may_gzip=*/true, &shared_body);
}

Response for_request_method(const Request& request, Response response) {
  if (request.method() == http::verb::head && !response.body().empty()) {
    const auto size = response.body().size();
    response.body().clear();
    response.content_length(size);
  }
  return response;
}

Response error_response(unsigned http_version, bool keep_alive, int status, const std::string& error,
                        const std::string& detail) {
  Response res{static_cast<http::status>(status), http_version};
  res.set(http::field::content_type, "application/json");
  // A full queue clears within a second at ingest rates: tell clients when to come back.
  if (status == 503) res.set(http::field::retry_after, "1");
  res.keep_alive(keep_alive);
  res.body() = json{{"error", error}, {"detail", detail}}.dump(-1, ' ', false, json::error_handler_t::replace);
  res.prepare_payload();
  return res;
}

}  // namespace wm::api
