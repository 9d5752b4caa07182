#pragma once

// The HTTP message types the api answers and the transport moves, and where a request's handler runs. Kept apart
// from the router so that the transport (server/http/) sees nothing of the handlers.
#include <boost/asio/buffer.hpp>
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/optional.hpp>
#include <memory>
#include <string>
#include <utility>

namespace wm::api {

using Request = boost::beast::http::request<boost::beast::http::string_body>;
using Response = boost::beast::http::response<boost::beast::http::string_body>;

/// A body that shares bytes kept elsewhere (the map's cached text) instead of holding a copy: what an answer made on
/// the I/O thread sends. Write-only (Beast's Body concept without a reader).
struct SharedTextBody {
  using value_type = std::shared_ptr<const std::string>;
  static std::uint64_t size(const value_type& body) { return body ? body->size() : 0; }
  class writer {
   public:
    using const_buffers_type = boost::asio::const_buffer;
    template <bool isRequest, class Fields>
    writer(const boost::beast::http::header<isRequest, Fields>&, const value_type& body) : body_(body) {}
    void init(boost::beast::error_code& ec) { ec = {}; }
    boost::optional<std::pair<const_buffers_type, bool>> get(boost::beast::error_code& ec) {
      ec = {};
      if (!body_ || body_->empty()) return boost::none;
      return std::make_pair(const_buffers_type(body_->data(), body_->size()), false);
    }

   private:
    const value_type& body_;
  };
};
using SharedResponse = boost::beast::http::response<SharedTextBody>;

/// Where the connection code runs a request's handler. `immediate`: on the I/O thread (cheap, never blocks:
/// health, the index, 404/405); `read`: the read threads of the handler pool, may take long (map, grid, queries,
/// dry runs); `write`: the pool's own threads for writes, which wait for the single writer (ingest, floor plans,
/// reloads).
enum class Lane { immediate, read, write };

}  // namespace wm::api
