#include "server/api/routes.h"

#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <sstream>

#include "tests/server/api/api_test_helpers.h"

namespace wm::testing {
namespace {

// "GET /api/v1/decisions?since=SEQ (WebSocket)" → "GET /api/v1/decisions".
std::string without_query(std::string name) {
  if (const auto space = name.find(' ', name.find(' ') + 1); space != std::string::npos) name.resize(space);
  return name.substr(0, name.find('?'));
}

std::set<std::string> table_routes() {
  std::set<std::string> names;
  for (const auto& route : api::routes()) names.insert(api::route_name(route));
  return names;
}

// The routes of the README's API reference: the first cell of each row of its table, every `METHOD /path`
// item, a bare `/path` item taking the method before it.
std::set<std::string> readme_routes() {
  std::ifstream in(std::string(WM_SOURCE_DIR) + "/README.md");
  EXPECT_TRUE(in) << "README.md not found under " << WM_SOURCE_DIR;
  std::set<std::string> names;
  std::string line;
  bool in_section = false;
  while (std::getline(in, line)) {
    if (line.rfind("## ", 0) == 0) in_section = line.find("HTTP API") != std::string::npos;
    if (!in_section || line.rfind("| `", 0) != 0) continue;
    const auto cell = line.substr(2, line.find(" |", 2) - 2);
    std::string method;
    for (std::size_t open = cell.find('`'); open != std::string::npos; open = cell.find('`', open)) {
      const auto close = cell.find('`', open + 1);
      std::string item = cell.substr(open + 1, close - open - 1);
      open = close + 1;
      if (const auto space = item.find(' '); space != std::string::npos && item.front() != '/') {
        method = item.substr(0, space);
        item = item.substr(space + 1);
      }
      EXPECT_FALSE(method.empty()) << "a path without a method in: " << line;
      names.insert(method + " " + item.substr(0, item.find('?')));
    }
  }
  return names;
}

TEST(RoutesTest, APlaceholderMatchesOneOrMoreCharactersSlashesIncluded) {
  std::string param;
  EXPECT_TRUE(api::pattern_matches("/api/v1/map", "/api/v1/map", param));
  EXPECT_EQ(param, "");
  EXPECT_FALSE(api::pattern_matches("/api/v1/map", "/api/v1/map/", param));
  EXPECT_TRUE(api::pattern_matches("/api/v1/elements/{id}", "/api/v1/elements/e12", param));
  EXPECT_EQ(param, "e12");
  EXPECT_TRUE(api::pattern_matches("/api/v1/elements/{id}/history", "/api/v1/elements/table-1/2/history", param));
  EXPECT_EQ(param, "table-1/2");
  EXPECT_FALSE(api::pattern_matches("/api/v1/elements/{id}", "/api/v1/elements/", param));
  EXPECT_FALSE(api::pattern_matches("/api/v1/elements/{id}/history", "/api/v1/elements/history", param));
}

TEST(RoutesTest, SeveralPlaceholdersMatchOneSegmentEach) {
  std::string param;
  const std::string_view tile = "/api/v1/grid/tiles/{layer}/{tx}/{ty}";
  EXPECT_TRUE(api::pattern_matches(tile, "/api/v1/grid/tiles/bayes/-3/12", param));
  EXPECT_EQ(param, "bayes/-3/12");
  EXPECT_FALSE(api::pattern_matches(tile, "/api/v1/grid/tiles/bayes/-3", param));
  EXPECT_FALSE(api::pattern_matches(tile, "/api/v1/grid/tiles/bayes/-3/12/4", param));
  EXPECT_FALSE(api::pattern_matches(tile, "/api/v1/grid/tiles/bayes//12", param));
  EXPECT_FALSE(api::pattern_matches(tile, "/api/v1/grid/tile/bayes/1/2", param));
  EXPECT_FALSE(api::pattern_matches(tile, "/api/v1/grid/tiles", param));
}

TEST(RoutesTest, HistoryRoutesComeBeforeTheIdRoutesTheyOverlap) {
  const auto match = api::find_route(http::verb::get, "/api/v1/objects/table-1/history");
  ASSERT_TRUE(match);
  EXPECT_EQ(match->route->pattern, "/api/v1/objects/{id}/history");
  EXPECT_EQ(match->param, "table-1");
  EXPECT_EQ(api::find_route(http::verb::get, "/api/v1/objects/table-1")->route->pattern, "/api/v1/objects/{id}");
}

TEST(RoutesTest, AllowListsTheMethodsOfThePathInTableOrder) {
  EXPECT_EQ(api::allowed_methods("/api/v1/floorplan"), "GET, HEAD, PUT");
  EXPECT_EQ(api::allowed_methods("/api/v1/primitives"), "POST");
  EXPECT_EQ(api::allowed_methods("/api/v1/elements/e1"), "GET, HEAD");
  EXPECT_EQ(api::allowed_methods("/api/v1/nothing"), "");
}

TEST(RoutesTest, OnlyTheEventsRouteIsAWebSocket) {
  EXPECT_TRUE(api::is_websocket_target("/api/v1/events"));
  EXPECT_TRUE(api::is_websocket_target("/api/v1/events?token=x"));
  EXPECT_FALSE(api::is_websocket_target("/api/v1/map"));
  EXPECT_FALSE(api::is_websocket_target("/api/v1/events/x"));
  auto upgrade = make_request(http::verb::get, "/api/v1/events");
  upgrade.set(http::field::connection, "Upgrade");
  upgrade.set(http::field::upgrade, "websocket");
  upgrade.set(http::field::sec_websocket_key, "dGhlIHNhbXBsZSBub25jZQ==");
  upgrade.set(http::field::sec_websocket_version, "13");
  EXPECT_TRUE(api::is_websocket_upgrade(upgrade));
  EXPECT_FALSE(api::is_websocket_upgrade(make_request(http::verb::get, "/api/v1/events")));
  upgrade.target("/api/v1/map");
  EXPECT_FALSE(api::is_websocket_upgrade(upgrade));
}

TEST(RoutesTest, EveryRouteRunsOnTheLaneTheTableGivesIt) {
  for (const auto& route : api::routes()) {
    std::string target(route.pattern);
    if (const auto open = target.find('{'); open != std::string::npos)
      target.replace(open, target.find('}') - open + 1, "x");
    EXPECT_EQ(api::handler_lane(make_request(route.method, target)), route.lane) << api::route_name(route);
  }
  EXPECT_EQ(api::handler_lane(make_request(http::verb::get, "/api/v1/health")), api::Lane::immediate);
  EXPECT_EQ(api::handler_lane(make_request(http::verb::post, "/api/v1/primitives")), api::Lane::write);
  EXPECT_EQ(api::handler_lane(make_request(http::verb::post, "/api/v1/query")), api::Lane::read);
  // A map's own route never runs on the I/O thread: in a cluster another node may answer it.
  EXPECT_EQ(api::handler_lane(make_request(http::verb::get, "/api/v1/maps/f1/health")), api::Lane::read);
  EXPECT_EQ(api::handler_lane(make_request(http::verb::post, "/api/v1/maps/f1/scans")), api::Lane::write);
  // No route: a 404 or 405 is answered at once, unless decoding may still find one.
  EXPECT_EQ(api::handler_lane(make_request(http::verb::delete_, "/api/v1/map")), api::Lane::immediate);
  EXPECT_EQ(api::handler_lane(make_request(http::verb::get, "/api/v1/objects%2Fx")), api::Lane::read);
}

class RouteTableTest : public ApiTest {};

TEST_F(RouteTableTest, EveryPathAnswersMethodsItDoesNotTakeWith405AndTheTablesAllow) {
  for (const auto& route : api::routes()) {
    std::string target(route.pattern);
    if (const auto open = target.find('{'); open != std::string::npos)
      target.replace(open, target.find('}') - open + 1, "x");
    for (const auto method : {http::verb::get, http::verb::put, http::verb::post, http::verb::delete_}) {
      if (api::find_route(method, target)) continue;
      const auto response = send(method, target);
      EXPECT_EQ(status_of(response), 405) << api::route_name(route);
      EXPECT_EQ(error_of(response), "method_not_allowed");
      EXPECT_EQ(response[http::field::allow], api::allowed_methods(target)) << target;
    }
  }
}

TEST_F(RouteTableTest, HeadIsTheGetWithoutItsBody) {
  const auto get = send(http::verb::get, "/api/v1");
  const auto head = send(http::verb::head, "/api/v1");
  ASSERT_EQ(status_of(head), 200);
  EXPECT_TRUE(head.body().empty());
  ASSERT_FALSE(get.body().empty());
  EXPECT_EQ(head[http::field::content_length], std::to_string(get.body().size()));
  EXPECT_EQ(head[http::field::content_type], get[http::field::content_type]);
  // Errors too: the headers only (a body would be read as the start of the next answer on the connection).
  for (const auto* target : {"/api/v1/primitives", "/api/v1/nothing", "/api/v1/elements/e404"}) {
    const auto error = send(http::verb::head, target);
    EXPECT_GE(status_of(error), 404) << target;
    EXPECT_TRUE(error.body().empty()) << target;
    EXPECT_NE(error[http::field::content_length], "0") << target;
  }
}

TEST_F(RouteTableTest, AnUnknownPathIs404) {
  const auto response = send(http::verb::get, "/api/v1/nothing");
  EXPECT_EQ(status_of(response), 404);
  EXPECT_EQ(error_of(response), "not_found");
  EXPECT_NE(json_of(response)["detail"].get<std::string>().find("/api/v1/nothing"), std::string::npos);
}

TEST_F(RouteTableTest, TheIndexListsEveryRouteOfTheTableTheEventsWebSocketIncluded) {
  const auto response = send(http::verb::get, "/api/v1");
  ASSERT_EQ(status_of(response), 200);
  const auto body = json_of(response);
  EXPECT_EQ(body["service"], "worldmodel");
  std::set<std::string> listed;
  for (const auto& endpoint : body["endpoints"]) listed.insert(without_query(endpoint.get<std::string>()));
  EXPECT_EQ(listed, table_routes());
  EXPECT_TRUE(listed.count("GET /api/v1/events"));
  EXPECT_EQ(body["endpoints"].size(), api::routes().size());
}

TEST_F(RouteTableTest, TheReadmeApiReferenceListsTheRoutesOfTheTable) { EXPECT_EQ(readme_routes(), table_routes()); }

}  // namespace
}  // namespace wm::testing

namespace wm::testing {
namespace {

std::string text_of(const api::SharedResponse& response) { return response.body() ? *response.body() : ""; }

// The I/O thread's try: GET /api/v1/map from bytes already made (or 304), everything else queued.
TEST_F(RouteTableTest, TheMapIsAnsweredAtOnceFromBytesAlreadyMadeAndQueuedOtherwise) {
  load_demo_plan();
  api::Services services{options_, world_};  // one map cache for every request below
  const auto get = make_request(http::verb::get, "/api/v1/map");
  EXPECT_FALSE(api::answer_at_once(get, services)) << "not made yet: a handler thread makes it";
  const auto built = api::handle_request(get, services);
  ASSERT_EQ(status_of(built), 200);
  const auto at_once = api::answer_at_once(get, services);
  ASSERT_TRUE(at_once);
  EXPECT_EQ(text_of(*at_once), built.body());
  EXPECT_EQ((*at_once)[http::field::etag], built[http::field::etag]);
  EXPECT_EQ(at_once->body().get(), api::answer_at_once(get, services)->body().get()) << "the cached bytes, shared";

  auto conditional = get;
  conditional.set(http::field::if_none_match, built[http::field::etag]);
  const auto not_modified = api::answer_at_once(conditional, services);
  ASSERT_TRUE(not_modified);
  EXPECT_EQ(not_modified->result_int(), 304u);

  auto head = make_request(http::verb::head, "/api/v1/map");
  const auto head_answer = api::answer_at_once(head, services);
  ASSERT_TRUE(head_answer);
  EXPECT_EQ(text_of(*head_answer), "");
  EXPECT_EQ((*head_answer)[http::field::content_length], std::to_string(built.body().size()));

  // The gzip form is compressed on a handler thread, once; then it too is served at once.
  auto gzip = get;
  gzip.set(http::field::accept_encoding, "gzip");
  EXPECT_FALSE(api::answer_at_once(gzip, services));
  ASSERT_EQ(api::handle_request(gzip, services)[http::field::content_encoding], "gzip");
  const auto gzip_at_once = api::answer_at_once(gzip, services);
  ASSERT_TRUE(gzip_at_once);
  EXPECT_EQ((*gzip_at_once)[http::field::content_encoding], "gzip");

  // A new version: queued (read-your-writes) unless the client accepts the older map.
  world_.state().version += 1;
  EXPECT_FALSE(api::answer_at_once(get, services));
  auto stale_ok = get;
  stale_ok.set(http::field::cache_control, "max-stale=60");
  const auto stale = api::answer_at_once(stale_ok, services);
  ASSERT_TRUE(stale);
  EXPECT_EQ(text_of(*stale), built.body());
  EXPECT_EQ((*stale)[http::field::age], "0");

  // Windows are cut per request, and no other route runs on the I/O thread; a bad parameter is answered there.
  EXPECT_FALSE(api::answer_at_once(make_request(http::verb::get, "/api/v1/map?bbox=0,0,1,1"), services));
  EXPECT_FALSE(api::answer_at_once(make_request(http::verb::get, "/api/v1/elements"), services));
  // A path with escapes goes to its lane, where it is decoded and looked up again (here: the same map).
  const auto escaped = make_request(http::verb::get, "/api/v1/m%61p");
  EXPECT_FALSE(api::answer_at_once(escaped, services));
  EXPECT_EQ(api::handler_lane(escaped), api::Lane::read);
  EXPECT_EQ(status_of(api::handle_request(escaped, services)), 200);
  const auto bad = api::answer_at_once(make_request(http::verb::get, "/api/v1/map?since=soon"), services);
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->result_int(), 400u);
  EXPECT_NE(text_of(*bad).find("since"), std::string::npos);
}

}  // namespace
}  // namespace wm::testing
