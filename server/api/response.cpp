#include "server/api/response.h"

#include "server/api/api_error.h"

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
