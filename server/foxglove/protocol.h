#pragma once

// The Foxglove WebSocket protocol, subprotocol "foxglove.websocket.v1"
// (https://github.com/foxglove/ws-protocol/blob/main/docs/spec.md): the server's JSON messages, the binary message
// data frame, and the client's JSON messages parsed into value types. No I/O here.
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace wm::foxglove {

/// The WebSocket subprotocol this server speaks; a client must offer it (Sec-WebSocket-Protocol).
inline constexpr std::string_view kSubprotocol = "foxglove.websocket.v1";

/// A client message that is not what the protocol describes (not JSON, no "op", a field of the wrong type).
class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One channel as advertised. Every channel of this server is JSON-encoded with a JSON Schema.
struct Channel {
  std::uint32_t id = 0;
  std::string topic;
  std::string schema_name;  // e.g. "foxglove.Grid": what Foxglove's panels recognise
  std::string schema;       // JSON Schema text
};

struct ServerInfo {
  std::string name;
  /// Tells a client whether it reconnected to the same server run (the map's server_instance).
  std::string session_id;
  std::map<std::string, std::string> metadata;
};

/// {"op": "serverInfo", ...}: no optional capability (clients cannot publish, call services or set parameters), so
/// supportedEncodings is empty.
std::string server_info_json(const ServerInfo& info);
/// {"op": "advertise", "channels": [...]}, encoding "json", schemaEncoding "jsonschema".
std::string advertise_json(const std::vector<Channel>& channels);

enum class StatusLevel { info = 0, warning = 1, error = 2 };
/// {"op": "status", "level", "message"}: what the client is told about its own requests and about dropped data.
std::string status_json(StatusLevel level, std::string_view message);

/// Size of the message data header: opcode 0x01, subscription id (u32 LE), receive time (u64 LE) [bytes].
inline constexpr std::size_t kMessageDataHeaderBytes = 13;
/// The header of a message data frame; the payload follows it in the same binary WebSocket message.
/// `receive_time_ns`: nanoseconds since the Unix epoch.
std::string message_data_header(std::uint32_t subscription_id, std::uint64_t receive_time_ns);

struct Subscription {
  std::uint32_t id = 0;  // chosen by the client
  std::uint32_t channel_id = 0;
};
struct Subscribe {
  std::vector<Subscription> subscriptions;
};
struct Unsubscribe {
  std::vector<std::uint32_t> subscription_ids;
};
/// A well-formed message this server does not implement (client publishing, parameters, services, ...).
struct Unsupported {
  std::string op;
};
using ClientMessage = std::variant<Subscribe, Unsubscribe, Unsupported>;

/// Parses one text message of a client. @throw ProtocolError naming what is wrong (not JSON, not an object, no "op",
/// a missing or mistyped field, an id outside 0 … 2^32 − 1).
ClientMessage parse_client_message(std::string_view text);

}  // namespace wm::foxglove
