#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "server/foxglove/protocol.h"
#include "server/foxglove/schemas.h"

namespace wm::foxglove {
namespace {

using nlohmann::json;

TEST(FoxgloveProtocolTest, MessageDataHeaderIsOpcodeSubscriptionAndTimeLittleEndian) {
  const auto header = message_data_header(0x04030201u, 0x0c0b0a0908070605ull);
  ASSERT_EQ(header.size(), kMessageDataHeaderBytes);
  const unsigned char expected[] = {0x01, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0a, 0x0b, 0x0c};
  for (std::size_t i = 0; i < sizeof expected; ++i)
    EXPECT_EQ(static_cast<unsigned char>(header[i]), expected[i]) << "byte " << i;
  // The largest values survive whole.
  const auto top = message_data_header(0xffffffffu, 0xffffffffffffffffull);
  for (std::size_t i = 1; i < top.size(); ++i) EXPECT_EQ(static_cast<unsigned char>(top[i]), 0xff) << "byte " << i;
}

TEST(FoxgloveProtocolTest, ServerInfoClaimsNoCapability) {
  const auto info = json::parse(server_info_json({"wmd", "abc123", {{"api", "/api/v1"}}}));
  EXPECT_EQ(info["op"], "serverInfo");
  EXPECT_EQ(info["name"], "wmd");
  EXPECT_EQ(info["sessionId"], "abc123");
  EXPECT_EQ(info["capabilities"], json::array());
  EXPECT_EQ(info["supportedEncodings"], json::array());
  EXPECT_EQ(info["metadata"], json({{"api", "/api/v1"}}));
}

TEST(FoxgloveProtocolTest, AdvertiseListsJsonChannelsWithTheirJsonSchemas) {
  const auto advertise = json::parse(
      advertise_json({{1, "/grid", "foxglove.Grid", schemas::grid()}, {6, "/decisions", "foxglove.Log", "{}"}}));
  EXPECT_EQ(advertise["op"], "advertise");
  ASSERT_EQ(advertise["channels"].size(), 2u);
  const auto& grid = advertise["channels"][0];
  EXPECT_EQ(grid["id"], 1);
  EXPECT_EQ(grid["topic"], "/grid");
  EXPECT_EQ(grid["encoding"], "json");
  EXPECT_EQ(grid["schemaName"], "foxglove.Grid");
  EXPECT_EQ(grid["schemaEncoding"], "jsonschema");
  // The schema is text, a JSON Schema that marks the cells as base64.
  const auto schema = json::parse(grid["schema"].get<std::string>());
  EXPECT_EQ(schema["properties"]["data"]["contentEncoding"], "base64");
  EXPECT_EQ(schema["properties"]["column_count"]["type"], "integer");
  EXPECT_EQ(advertise["channels"][1]["id"], 6);
}

TEST(FoxgloveProtocolTest, EverySchemaNamesItsFoxgloveTypeAndDescribesTimestamps) {
  for (const auto& [text, title] :
       std::vector<std::pair<std::string, std::string>>{{schemas::grid(), "foxglove.Grid"},
                                                        {schemas::scene_update(), "foxglove.SceneUpdate"},
                                                        {schemas::pose_in_frame(), "foxglove.PoseInFrame"},
                                                        {schemas::frame_transforms(), "foxglove.FrameTransforms"},
                                                        {schemas::log(), "foxglove.Log"}}) {
    const auto schema = json::parse(text);
    EXPECT_EQ(schema["title"], title);
    EXPECT_EQ(schema["type"], "object");
  }
  const auto log = json::parse(schemas::log());
  EXPECT_EQ(log["properties"]["timestamp"]["properties"]["nsec"]["maximum"], 999999999);
  const auto scene = json::parse(schemas::scene_update());
  EXPECT_EQ(scene["properties"]["entities"]["items"]["properties"]["lines"]["items"]["properties"]["points"]["items"]
                 ["properties"]["z"]["type"],
            "number");
}

TEST(FoxgloveProtocolTest, StatusCarriesItsLevelAsANumber) {
  const auto status = json::parse(status_json(StatusLevel::warning, "behind"));
  EXPECT_EQ(status["op"], "status");
  EXPECT_EQ(status["level"], 1);
  EXPECT_EQ(status["message"], "behind");
  EXPECT_EQ(json::parse(status_json(StatusLevel::error, "x"))["level"], 2);
}

TEST(FoxgloveProtocolTest, ParsesSubscribeAndUnsubscribe) {
  const auto subscribe = parse_client_message(
      R"({"op":"subscribe","subscriptions":[{"id":0,"channelId":3},{"id":4294967295,"channelId":7}]})");
  const auto* s = std::get_if<Subscribe>(&subscribe);
  ASSERT_NE(s, nullptr);
  ASSERT_EQ(s->subscriptions.size(), 2u);
  EXPECT_EQ(s->subscriptions[0].id, 0u);
  EXPECT_EQ(s->subscriptions[0].channel_id, 3u);
  EXPECT_EQ(s->subscriptions[1].id, 4294967295u);
  EXPECT_EQ(s->subscriptions[1].channel_id, 7u);

  const auto unsubscribe = parse_client_message(R"({"op":"unsubscribe","subscriptionIds":[5,0]})");
  const auto* u = std::get_if<Unsubscribe>(&unsubscribe);
  ASSERT_NE(u, nullptr);
  EXPECT_EQ(u->subscription_ids, (std::vector<std::uint32_t>{5, 0}));
}

TEST(FoxgloveProtocolTest, AnOperationItDoesNotImplementIsNamedNotRefused) {
  const auto message = parse_client_message(R"({"op":"advertise","channels":[]})");
  const auto* other = std::get_if<Unsupported>(&message);
  ASSERT_NE(other, nullptr);
  EXPECT_EQ(other->op, "advertise");
}

TEST(FoxgloveProtocolTest, MalformedMessagesThrowNamingWhatIsWrong) {
  const auto error_of = [](const std::string& text) {
    try {
      parse_client_message(text);
    } catch (const ProtocolError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("subscribe").find("not JSON"), std::string::npos);
  EXPECT_EQ(error_of("[1]"), "not a JSON object");
  EXPECT_EQ(error_of(R"({"subscriptions":[]})"), "op: missing or not a string");
  EXPECT_EQ(error_of(R"({"op":3})"), "op: missing or not a string");
  EXPECT_EQ(error_of(R"({"op":"subscribe"})"), "subscriptions: missing");
  EXPECT_EQ(error_of(R"({"op":"subscribe","subscriptions":{}})"), "subscriptions: not an array");
  EXPECT_EQ(error_of(R"({"op":"subscribe","subscriptions":[3]})"), "subscriptions[0]: not an object");
  EXPECT_EQ(error_of(R"({"op":"subscribe","subscriptions":[{"id":1}]})"), "subscriptions[0].channelId: missing");
  EXPECT_EQ(error_of(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":2},{"id":-1,"channelId":2}]})"),
            "subscriptions[1].id: not between 0 and 4294967295");
  EXPECT_EQ(error_of(R"({"op":"subscribe","subscriptions":[{"id":4294967296,"channelId":2}]})"),
            "subscriptions[0].id: not between 0 and 4294967295");
  EXPECT_EQ(error_of(R"({"op":"subscribe","subscriptions":[{"id":1.5,"channelId":2}]})"),
            "subscriptions[0].id: not an integer");
  EXPECT_EQ(error_of(R"({"op":"unsubscribe","subscriptionIds":["1"]})"), "subscriptionIds[0]: not an integer");
  // Found by fuzz_foxglove: a number beyond a double made nlohmann throw out_of_range, not a parse error.
  EXPECT_NE(error_of(R"({"op":"subscribe","subscriptions":[{"id":1e309,"channelId":2}]})").find("not JSON"),
            std::string::npos);
  EXPECT_NE(error_of("1.7976931348623157e309\"a").find("not JSON"), std::string::npos);
  // A megabyte of '[' would overflow the stack when nlohmann destroys its DOM: refused before parsing.
  EXPECT_EQ(error_of(std::string(1 << 20, '[')), "JSON nested deeper than 64 levels at byte 64");
}

}  // namespace
}  // namespace wm::foxglove
