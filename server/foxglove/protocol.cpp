#include "server/foxglove/protocol.h"

#include <limits>
#include <nlohmann/json.hpp>

#include "apriori/import/json_limits.h"

namespace wm::foxglove {
namespace {

using json = nlohmann::json;

std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

std::uint32_t to_u32(const json& value, const std::string& where) {
  if (!value.is_number_integer()) throw ProtocolError(where + ": not an integer");
  // Unsigned and signed JSON integers both arrive here; anything outside u32 is refused, not wrapped.
  if (value.is_number_unsigned()) {
    const auto n = value.get<std::uint64_t>();
    if (n <= std::numeric_limits<std::uint32_t>::max()) return static_cast<std::uint32_t>(n);
  }
  throw ProtocolError(where + ": not between 0 and 4294967295");
}

std::uint32_t u32_field(const json& object, const char* name, const std::string& where) {
  const auto it = object.find(name);
  if (it == object.end()) throw ProtocolError(where + "." + name + ": missing");
  return to_u32(*it, where + "." + name);
}

const json& array_field(const json& object, const char* name) {
  const auto it = object.find(name);
  if (it == object.end()) throw ProtocolError(std::string(name) + ": missing");
  if (!it->is_array()) throw ProtocolError(std::string(name) + ": not an array");
  return *it;
}

}  // namespace

std::string server_info_json(const ServerInfo& info) {
  json metadata = json::object();
  for (const auto& [key, value] : info.metadata) metadata[key] = value;
  return dump({{"op", "serverInfo"},
               {"name", info.name},
               {"capabilities", json::array()},
               {"supportedEncodings", json::array()},
               {"metadata", std::move(metadata)},
               {"sessionId", info.session_id}});
}

std::string advertise_json(const std::vector<Channel>& channels) {
  json list = json::array();
  for (const auto& c : channels)
    list.push_back({{"id", c.id},
                    {"topic", c.topic},
                    {"encoding", "json"},
                    {"schemaName", c.schema_name},
                    {"schema", c.schema},
                    {"schemaEncoding", "jsonschema"}});
  return dump({{"op", "advertise"}, {"channels", std::move(list)}});
}

std::string status_json(StatusLevel level, std::string_view message) {
  return dump({{"op", "status"}, {"level", static_cast<int>(level)}, {"message", message}});
}

std::string message_data_header(std::uint32_t subscription_id, std::uint64_t receive_time_ns) {
  std::string header(kMessageDataHeaderBytes, '\0');
  header[0] = '\x01';
  // Little-endian whatever the host's byte order (the protocol says LE).
  for (int i = 0; i < 4; ++i) header[1 + i] = static_cast<char>((subscription_id >> (8 * i)) & 0xff);
  for (int i = 0; i < 8; ++i) header[5 + i] = static_cast<char>((receive_time_ns >> (8 * i)) & 0xff);
  return header;
}

ClientMessage parse_client_message(std::string_view text) {
  // nlohmann's DOM is destroyed recursively: a client's megabyte of '[' would overflow the stack.
  if (const auto too_deep = apriori::json_nesting_error(text)) throw ProtocolError(*too_deep);
  json message;
  try {
    message = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number beyond a double (1e309)
    throw ProtocolError(std::string("not JSON: ") + e.what());
  }
  if (!message.is_object()) throw ProtocolError("not a JSON object");
  const auto op_it = message.find("op");
  if (op_it == message.end() || !op_it->is_string()) throw ProtocolError("op: missing or not a string");
  const auto op = op_it->get<std::string>();
  if (op == "subscribe") {
    Subscribe subscribe;
    const auto& list = array_field(message, "subscriptions");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const auto where = "subscriptions[" + std::to_string(i) + "]";
      if (!list[i].is_object()) throw ProtocolError(where + ": not an object");
      subscribe.subscriptions.push_back({u32_field(list[i], "id", where), u32_field(list[i], "channelId", where)});
    }
    return subscribe;
  }
  if (op == "unsubscribe") {
    Unsubscribe unsubscribe;
    const auto& list = array_field(message, "subscriptionIds");
    for (std::size_t i = 0; i < list.size(); ++i)
      unsubscribe.subscription_ids.push_back(to_u32(list[i], "subscriptionIds[" + std::to_string(i) + "]"));
    return unsubscribe;
  }
  return Unsupported{op};
}

}  // namespace wm::foxglove
