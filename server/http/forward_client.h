#pragma once

// Node to node: a request passed on, as it came, to the node of a cluster that serves its map.
#include <chrono>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

#include "server/api/http_types.h"

namespace wm::http {

/// No whole answer came from the other node (refused, reset, timed out): the request may or may not have been
/// applied there (a client retries with its Idempotency-Key).
class ForwardError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A node's address as its URL gives it: "http://HOST:PORT" (a trailing '/' allowed; HOST may be "[v6]").
struct NodeAddress {
  std::string host;  // as written, brackets included
  std::string port;
};
/// nullopt for anything else (another scheme, no port, a path).
std::optional<NodeAddress> parse_node_url(const std::string& url);

/// Sends `request` to the node at `base_url` ("http://host:port") on a connection of its own, with its Host set to
/// that node's, and returns the answer as it came (its Connection header left to the caller). While it waits,
/// `still_worth_it` is asked every `check_every`; false (the node no longer serves the map: paused past its lease)
/// gives up at once. @throw ForwardError after `timeout`, on giving up, or when the node does not answer.
api::Response forward_request(api::Request request, const std::string& base_url, std::chrono::milliseconds timeout,
                              const std::function<bool()>& still_worth_it = {},
                              std::chrono::milliseconds check_every = std::chrono::milliseconds(500));

}  // namespace wm::http
