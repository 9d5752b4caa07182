#include <unistd.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

struct BadRequestCase {
  const char* name;
  const char* method;
  const char* target;
  std::string body;
  const char* content_type;
  int status;
  const char* detail_contains;
};

class BadInputTest : public ServerFixture {
 protected:
  void SetUp() override {
    ServerFixture::SetUp();
    send_json("PUT", "/api/v1/floorplan", lab_plan());
    send_json("POST", "/api/v1/primitives", {{"segments", {{{"p0", {10, 3}}, {"p1", {13, 3}}}}}});
  }
};

// Each kind of bad input gets a JSON error with the right status, and the map stays exactly as it was.
TEST_F(BadInputTest, EveryKindOfBadInputIsRefusedAndChangesNothing) {
  const std::string map_before = call("GET", "/api/v1/map").body;
  const std::string log_before = call("GET", "/api/v1/decisions").body;
  const std::string ok_segment = R"({"p0": [1, 1], "p1": [2, 1]})";
  const std::vector<BadRequestCase> cases = {
      {"malformed JSON", "POST", "/api/v1/primitives", R"({"segments": [)", "application/json", 400, "malformed JSON"},
      {"not an object", "POST", "/api/v1/primitives", "[1, 2, 3]", "application/json", 400, "expected an object"},
      {"wrong type", "POST", "/api/v1/primitives", R"({"segments": [{"p0": ["1", 1], "p1": [2, 1]}]})",
       "application/json", 400, "segments[0].p0[0]"},
      {"missing field", "POST", "/api/v1/primitives", R"({"segments": [{"p0": [1, 1]}]})", "application/json", 400,
       "segments[0].p1"},
      {"NaN literal", "POST", "/api/v1/primitives", R"({"segments": [{"p0": [NaN, 1], "p1": [2, 1]}]})",
       "application/json", 400, "malformed JSON"},
      {"infinity by overflow", "POST", "/api/v1/primitives", R"({"segments": [{"p0": [1e999, 1], "p1": [2, 1]}]})",
       "application/json", 400, "number overflow parsing '1e999'"},
      {"absurd coordinate", "POST", "/api/v1/primitives", R"({"segments": [{"p0": [1e12, 1], "p1": [2, 1]}]})",
       "application/json", 400, "absurd"},
      {"zero-length segment", "POST", "/api/v1/primitives", R"({"segments": [{"p0": [1, 1], "p1": [1, 1]}]})",
       "application/json", 400, "shorter"},
      {"bad covariance", "POST", "/api/v1/primitives",
       R"({"segments": [{"p0": [1, 1], "p1": [2, 1], "cov": [[1, 0], [0, -1]]}]})", "application/json", 400,
       "positive definite"},
      {"unknown field", "POST", "/api/v1/primitives", R"({"segmnets": []})", "application/json", 400, "segmnets"},
      {"empty segments", "POST", "/api/v1/primitives", R"({"segments": []})", "application/json", 400, "empty"},
      // A bad segment after a good one: the request is refused whole, the good one is not applied either.
      {"bad second segment", "POST", "/api/v1/primitives",
       std::string(R"({"segments": [)") + ok_segment + R"(, {"p0": [1, 1], "p1": [1, "x"]}]})", "application/json", 400,
       "segments[1].p1[1]"},
      {"empty body", "POST", "/api/v1/primitives", "", "application/json", 400, "empty body"},
      {"wrong content type", "POST", "/api/v1/primitives", std::string(R"({"segments": [)") + ok_segment + "]}",
       "text/plain", 415, "application/json"},
      {"truncated DXF", "PUT", "/api/v1/floorplan", "0\nSECTION\n", "image/vnd.dxf", 400, ""},
      {"binary DXF", "PUT", "/api/v1/floorplan", std::string("AutoCAD Binary DXF\r\n\x1a\0", 22), "image/vnd.dxf", 400,
       "inary"},
      {"bad import envelope", "PUT", "/api/v1/floorplan", R"({"import": {"format": "dwg", "data": "x"}})",
       "application/json", 400, "import.format"},
      {"bad floor plan", "PUT", "/api/v1/floorplan",
       R"({"objects": [{"id": "a", "kind": "wall", "segments": [[[0, 0]]]}]})", "application/json", 400,
       "objects[0].segments[0]"},
      {"floor plan NaN pose", "PUT", "/api/v1/floorplan",
       R"({"objects": [{"id": "a", "kind": "wall", "pose": {"x": 1e400, "y": 0, "theta": 0}, "segments": [[[0, 0], [1, 0]]]}]})",
       "application/json", 400, "number overflow parsing '1e400'"},
      {"unknown path", "GET", "/api/v1/nothing", "", "application/json", 404, "/api/v1/nothing"},
      {"wrong method", "DELETE", "/api/v1/map", "", "application/json", 405, "GET"},
      {"bad query", "GET", "/api/v1/decisions?since=abc", "", "application/json", 400, "since"},
  };
  for (const auto& c : cases) {
    const auto r = call(c.method, c.target, c.body, c.content_type);
    EXPECT_EQ(r.status, c.status) << c.name << ": " << r.body;
    EXPECT_NE(r.content_type.find("application/json"), std::string::npos) << c.name;
    const auto body = json::parse(r.body, nullptr, false);
    ASSERT_TRUE(body.is_object()) << c.name << ": " << r.body;
    EXPECT_TRUE(body.contains("error")) << c.name;
    EXPECT_NE(body.value("detail", "").find(c.detail_contains), std::string::npos)
        << c.name << ": detail was '" << body.value("detail", "") << "'";
  }
  EXPECT_EQ(call("GET", "/api/v1/map").body, map_before);
  EXPECT_EQ(call("GET", "/api/v1/decisions").body, log_before);
}

TEST_F(BadInputTest, OversizedBodyGets413AndTheServerKeepsServing) {
  const std::string map_before = call("GET", "/api/v1/map").body;
  std::string huge = R"({"segments": [)";
  const std::string one = R"({"p0": [1, 1], "p1": [2, 1]},)";
  while (huge.size() < (17u << 20)) huge += one;
  huge += R"({"p0": [1, 1], "p1": [2, 1]}]})";
  const auto r = call("POST", "/api/v1/primitives", huge);
  EXPECT_EQ(r.status, 413) << r.body.substr(0, 200);
  EXPECT_EQ(call("GET", "/api/v1/map").body, map_before);
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
}

TEST_F(BadInputTest, GarbageOnTheSocketGets400AndTheServerKeepsServing) {
  namespace net = boost::asio;
  net::io_context ioc;
  net::ip::tcp::socket socket(ioc);
  socket.connect({net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(server_->port())});
  const std::string garbage = "THIS IS NOT HTTP\r\n\r\n";
  net::write(socket, net::buffer(garbage));
  std::string answer;
  boost::system::error_code ec;
  char buffer[1024];
  for (std::size_t n; (n = socket.read_some(net::buffer(buffer), ec)) > 0 && !ec;) answer.append(buffer, n);
  EXPECT_NE(answer.find("400"), std::string::npos) << answer;
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
}

TEST_F(ServerFixture, TokenGuardsStateChanges) {
  server_->stop();
  server_ = std::make_unique<WmdProcess>(std::vector<std::string>{"--db", (dir_.path() / "token.db").string(), "--port",
                                                                  "0", "--rules", WM_RULES_DIR, "--token", "s3cret"});
  client::HttpClient http(server_->url());
  EXPECT_EQ(http.request("PUT", "/api/v1/floorplan", lab_plan().dump()).status, 401);
  EXPECT_EQ(http.request("PUT", "/api/v1/floorplan", lab_plan().dump(), "application/json", "wrong").status, 401);
  EXPECT_EQ(http.request("PUT", "/api/v1/floorplan", lab_plan().dump(), "application/json", "s3cret").status, 200);
  EXPECT_EQ(http.request("GET", "/api/v1/map").status, 200);  // reading needs no token
}

}  // namespace
}  // namespace wm::testing
