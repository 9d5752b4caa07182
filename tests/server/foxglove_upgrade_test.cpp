#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "server/api/access.h"
#include "server/api/router.h"
#include "server/api/routes.h"
#include "server/foxglove/protocol.h"
#include "tests/server/api/api_test_helpers.h"

namespace wm::testing {
namespace {

// The upgrade of GET /foxglove as the api decides it, before the transport takes the connection over.
class FoxgloveUpgradeTest : public ApiTest {
 protected:
  static api::Request upgrade(const std::string& target, const std::string& protocols) {
    auto request = make_request(http::verb::get, target);
    request.set(http::field::connection, "Upgrade");
    request.set(http::field::upgrade, "websocket");
    request.set(http::field::sec_websocket_version, "13");
    request.set(http::field::sec_websocket_key, "dGhlIHNhbXBsZSBub25jZQ==");
    if (!protocols.empty()) request.set(http::field::sec_websocket_protocol, protocols);
    return request;
  }
  std::optional<api::Response> authorize(const api::Request& request) {
    api::Services services{options_, world_};
    return api::authorize_events(request, services);
  }
};

TEST_F(FoxgloveUpgradeTest, TheRouteSpeaksTheBridgesSubprotocol) {
  const auto request = upgrade("/foxglove", std::string(foxglove::kSubprotocol));
  EXPECT_TRUE(api::is_websocket_upgrade(request));
  EXPECT_EQ(api::websocket_subprotocol(request), foxglove::kSubprotocol);
  EXPECT_EQ(api::websocket_subprotocol(upgrade("/api/v1/events", "")), "") << "the events stream speaks none";
  EXPECT_EQ(api::websocket_subprotocol(upgrade("/api/v1/map", "")), "");
}

TEST_F(FoxgloveUpgradeTest, AnUpgradeThatOffersTheSubprotocolIsAllowed) {
  EXPECT_FALSE(authorize(upgrade("/foxglove", "foxglove.websocket.v1")));
  // Offered among others, in one header or several, with spaces.
  EXPECT_FALSE(authorize(upgrade("/foxglove", "foxglove.websocket.v2, foxglove.websocket.v1")));
  auto two_lines = upgrade("/foxglove", "x-other");
  two_lines.insert(http::field::sec_websocket_protocol, " foxglove.websocket.v1 ");
  EXPECT_FALSE(authorize(two_lines));
}

TEST_F(FoxgloveUpgradeTest, AnUpgradeWithoutTheSubprotocolIsRefusedWithAJsonError) {
  for (const std::string offered : {"", "foxglove.websocket.v2", "Foxglove.Websocket.V1", "foxglove.websocket.v1x"}) {
    const auto refusal = authorize(upgrade("/foxglove", offered));
    ASSERT_TRUE(refusal) << offered;
    EXPECT_EQ(status_of(*refusal), 400) << offered;
    EXPECT_EQ(error_of(*refusal), "subprotocol_required") << offered;
    EXPECT_NE(json_of(*refusal)["detail"].get<std::string>().find("Sec-WebSocket-Protocol: foxglove.websocket.v1"),
              std::string::npos);
  }
  EXPECT_FALSE(authorize(upgrade("/api/v1/events", ""))) << "the events stream needs no subprotocol";
}

TEST_F(FoxgloveUpgradeTest, TheTokenAndTheOriginAreCheckedAsForTheEvents) {
  options_.token = "s3cret";
  const auto no_token = authorize(upgrade("/foxglove", "foxglove.websocket.v1"));
  ASSERT_TRUE(no_token);
  EXPECT_EQ(status_of(*no_token), 401);
  EXPECT_FALSE(authorize(upgrade("/foxglove?token=s3cret", "foxglove.websocket.v1")));
  auto bearer = upgrade("/foxglove", "foxglove.websocket.v1");
  bearer.set(http::field::authorization, "Bearer s3cret");
  EXPECT_FALSE(authorize(bearer));
  // The token is checked before the subprotocol: a client without it learns nothing more.
  EXPECT_EQ(status_of(*authorize(upgrade("/foxglove", ""))), 401);
  auto cross_site = upgrade("/foxglove?token=s3cret", "foxglove.websocket.v1");
  cross_site.set(http::field::origin, "http://evil.example");
  EXPECT_EQ(status_of(*authorize(cross_site)), 403);
}

TEST_F(FoxgloveUpgradeTest, APlainGetIsToldToUpgradeWithTheSubprotocol) {
  const auto response = send(http::verb::get, "/foxglove");
  EXPECT_EQ(status_of(response), 426);
  EXPECT_EQ(error_of(response), "upgrade_required");
  EXPECT_EQ(response[http::field::upgrade], "websocket");
  EXPECT_NE(json_of(response)["detail"].get<std::string>().find("foxglove.websocket.v1"), std::string::npos);
  // The index lists it as a WebSocket.
  const auto index = json_of(send(http::verb::get, "/api/v1"));
  EXPECT_NE(std::find(index["endpoints"].begin(), index["endpoints"].end(), "GET /foxglove?token=TOKEN (WebSocket)"),
            index["endpoints"].end());
}

}  // namespace
}  // namespace wm::testing
