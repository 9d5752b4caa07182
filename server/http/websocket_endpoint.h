#pragma once

// A WebSocket whose messages mean something to someone else (the Foxglove bridge): the transport moves the bytes,
// the endpoint says what they mean. Kept free of Beast so that an endpoint needs nothing of the transport.
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace wm::http {

/// One WebSocket message to send: `head` then `body` (shared with other connections, not copied), as one message.
struct WebSocketFrame {
  bool binary = false;
  std::string head;
  std::shared_ptr<const std::string> body;  // may be null
  bool close_after = false;                 // the transport closes the connection (1013, try again later) after it
};

/// What the transport calls on an upgraded connection. open, receive, take and close are called on the connection's
/// strand, one at a time; none may block, and none may throw (the transport closes the connection if one does).
class WebSocketEndpoint {
 public:
  virtual ~WebSocketEndpoint() = default;
  /// The subprotocol to answer in Sec-WebSocket-Protocol (the client offered it: the api checked); empty: none.
  virtual std::string_view subprotocol() const = 0;
  /// After the handshake. `wake` may be called from any thread, must not block, and asks the transport to call
  /// take() soon; it does nothing once the connection is gone.
  virtual void open(std::function<void()> wake) = 0;
  /// One whole message from the client.
  virtual void receive(std::string_view message, bool binary) = 0;
  /// What to send now, in order; the transport calls it again when these are written (and after each wake).
  virtual std::vector<WebSocketFrame> take() = 0;
  /// The connection is gone (closed by either side, or failed); nothing is called after it.
  virtual void close() = 0;
};

}  // namespace wm::http
