#pragma once

// The HTTP message types the api answers and the transport moves, and where a request's handler runs. Kept apart
// from the router so that the transport (server/http/) sees nothing of the handlers.
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>

namespace wm::api {

using Request = boost::beast::http::request<boost::beast::http::string_body>;
using Response = boost::beast::http::response<boost::beast::http::string_body>;

/// Where the connection code runs a request's handler. `immediate`: on the I/O thread (cheap, never blocks:
/// health, the index, 404/405); `read`: the read threads of the handler pool, may take long (map, grid, queries,
/// dry runs); `write`: the pool's own threads for writes, which wait for the single writer (ingest, floor plans,
/// reloads).
enum class Lane { immediate, read, write };

}  // namespace wm::api
