// Two wmd nodes of a cluster on one PostgreSQL: a map made on one is served through the other (its answer names the
// node and the lease epoch), the list and the status name who serves what, events asked of the node that does not
// serve a map say where it is, a request that claims to come from another node needs the cluster's token and is
// never passed on again, a clean stop hands its maps to the other node, and start options that cannot make a node
// are refused with the reason.
#include <chrono>
#include <cstdlib>
#include <thread>

#include "e2e_fixture.h"
#include "support/postgres_server.h"

namespace wm::testing {
namespace {

namespace http = boost::beast::http;
constexpr char kToken[] = "node-test-token-0123456789";

class ClusterNodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    uri_ = postgres().uri();
    ::setenv("WM_CLUSTER_TOKEN", kToken, 1);
    // Long node ids (the cluster's name and a letter) that differ only at their end: each node's own schema stays its
    // own.
    cluster_ = schema_for(::testing::UnitTest::GetInstance()->current_test_info()->name());
    a_ = start("a");
    b_ = start("b");
  }
  void TearDown() override { ::unsetenv("WM_CLUSTER_TOKEN"); }

  std::unique_ptr<WmdProcess> start(const std::string& node) {
    return std::make_unique<WmdProcess>(std::vector<std::string>{"--store", uri_, "--cluster-id", cluster_, "--node-id",
                                                                 cluster_ + "-" + node, "--port", "0", "--rules",
                                                                 WM_RULES_DIR, "--no-shm"});
  }
  static http::response<http::string_body> request(int port, http::verb verb, const std::string& target,
                                                   const Headers& extra = {}, const std::string& body = {}) {
    Headers headers{{"Host", "127.0.0.1"}};
    headers.insert(headers.end(), extra.begin(), extra.end());
    return raw_request(port, verb, target, headers, body, std::chrono::seconds(30));
  }
  // The node serving `map` once the cluster says one does.
  std::string owner(int port, const std::string& map) {
    for (int i = 0; i < 100; ++i) {
      const auto r = request(port, http::verb::get, "/api/v1/maps/" + map + "/health");
      if (r.result_int() == 200) return std::string(r["X-WM-Node"]);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return {};
  }

  std::string uri_, cluster_;
  std::unique_ptr<WmdProcess> a_, b_;
};

TEST_F(ClusterNodeTest, AnyNodeAnswersForAMapAndAForgedOrLoopingForwardIsRefused) {
  const auto made = request(a_->port(), http::verb::post, "/api/v1/maps", {}, R"({"id": "f1"})");
  ASSERT_EQ(made.result_int(), 201u) << made.body();
  const auto node_a = cluster_ + "-a";
  ASSERT_EQ(owner(b_->port(), "f1"), node_a);  // asked of b, served by a

  // A scan posted to b lands in a's map, once, under a's lease.
  const json primitives{{"source", "r1"},
                        {"segments", {{{"p0", {0, 0}}, {"p1", {0, 4}}, {"cov", {{1e-4, 0}, {0, 1e-4}}}}}}};
  const auto posted = request(b_->port(), http::verb::post, "/api/v1/maps/f1/primitives", {{"Idempotency-Key", "k1"}},
                              primitives.dump());
  ASSERT_EQ(posted.result_int(), 200u) << posted.body();
  EXPECT_EQ(posted["X-WM-Node"], node_a);
  EXPECT_FALSE(posted["X-WM-Epoch"].empty());
  const auto again = request(b_->port(), http::verb::post, "/api/v1/maps/f1/primitives", {{"Idempotency-Key", "k1"}},
                             primitives.dump());
  EXPECT_EQ(again["Idempotent-Replayed"], "true");
  const auto elements = json::parse(request(a_->port(), http::verb::get, "/api/v1/maps/f1/elements").body());
  EXPECT_EQ(elements["elements"].size(), 1u);

  // The list and the status, asked of b, say a serves it.
  const auto maps = json::parse(request(b_->port(), http::verb::get, "/api/v1/maps").body());
  bool listed = false;
  for (const auto& m : maps["maps"])
    if (m["id"] == "f1") {
      listed = true;
      EXPECT_EQ(m["node"], node_a);
      EXPECT_EQ(m["owner"], a_->url());
    }
  EXPECT_TRUE(listed) << maps.dump();
  const auto status = json::parse(request(b_->port(), http::verb::get, "/api/v1/cluster").body());
  EXPECT_EQ(status["cluster"], cluster_);
  EXPECT_EQ(status["nodes"].size(), 2u) << status.dump();
  bool leased = false;
  for (const auto& lease : status["leases"])
    if (lease["map"] == "f1") leased = lease["node"] == node_a && lease["live"] == true;
  EXPECT_TRUE(leased) << status.dump();

  // Claiming to be a node: without the token, or with a wrong one, 403; with it, never passed on again (503).
  for (const Headers& forged : {Headers{{"X-WM-Forwarded-By", "x"}},
                                Headers{{"X-WM-Forwarded-By", "x"}, {"X-WM-Cluster-Token", "wrong-token-0123456789"}},
                                Headers{{"X-WM-Forwarded-By", "x"}, {"X-WM-Cluster-Token", ""}}}) {
    const auto r = request(b_->port(), http::verb::post, "/api/v1/maps/f1/primitives", forged, primitives.dump());
    EXPECT_EQ(r.result_int(), 403u) << r.body();
  }
  const auto looped = request(b_->port(), http::verb::get, "/api/v1/maps/f1/health",
                              {{"X-WM-Forwarded-By", "x"}, {"X-WM-Cluster-Token", kToken}});
  EXPECT_EQ(looped.result_int(), 503u);
  EXPECT_NE(looped.body().find("map_moved"), std::string::npos) << looped.body();
  // A map no node has is 404 on every node, as without a cluster; the token changes nothing on a's own map.
  EXPECT_EQ(request(b_->port(), http::verb::get, "/api/v1/maps/nope/health").result_int(), 404u);
  EXPECT_EQ(request(a_->port(), http::verb::get, "/api/v1/maps/f1/health",
                    {{"X-WM-Forwarded-By", "x"}, {"X-WM-Cluster-Token", kToken}})
                .result_int(),
            200u);

  // Events asked of b: where the map is, then the stream closes.
  EventClient follower(b_->port(), "/api/v1/maps/f1/events");
  EXPECT_EQ(follower.next()["type"], "hello");
  const auto moved = follower.next();
  EXPECT_EQ(moved["type"], "map_moved");
  EXPECT_EQ(moved["owner"], a_->url());
  // A Foxglove client of the map, at b: refused with where to connect (its connection is not passed on).
  const auto foxglove = request(b_->port(), http::verb::get, "/foxglove?map=f1",
                                {{"Upgrade", "websocket"},
                                 {"Connection", "Upgrade"},
                                 {"Sec-WebSocket-Version", "13"},
                                 {"Sec-WebSocket-Protocol", "foxglove.websocket.v1"},
                                 {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="}});
  EXPECT_EQ(foxglove.result_int(), 503u) << foxglove.body();
  EXPECT_NE(foxglove.body().find(a_->url() + "/foxglove?map=f1"), std::string::npos) << foxglove.body();
  // a stops cleanly (its leases given back): b serves the map at its next round, with what a committed.
  ASSERT_EQ(a_->stop(), 0) << a_->output();
  EXPECT_EQ(owner(b_->port(), "f1"), cluster_ + "-b");
  EXPECT_EQ(json::parse(request(b_->port(), http::verb::get, "/api/v1/maps/f1/elements").body())["elements"].size(),
            1u);
}

TEST(ClusterStartTest, OptionsThatCannotMakeANodeAreRefusedWithTheReason) {
  const std::string wmd = std::string(WM_WMD_PATH) + " --port 0 ";
  const std::string store = "--store " + postgres().uri() + " ";
  ::unsetenv("WM_CLUSTER_TOKEN");
  auto r = run_command(wmd + store + "--cluster-id c1");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("WM_CLUSTER_TOKEN"), std::string::npos) << r.output;
  r = run_command("WM_CLUSTER_TOKEN=short " + wmd + store + "--cluster-id c1");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("at least 16"), std::string::npos) << r.output;
  r = run_command("WM_CLUSTER_TOKEN=0123456789abcdefgh " + wmd + "--db /tmp/x.db --cluster-id c1");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("PostgreSQL"), std::string::npos) << r.output;
  r = run_command("WM_CLUSTER_TOKEN=0123456789abcdefgh " + wmd + store + "--cluster-id 'a b'");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--cluster-id"), std::string::npos) << r.output;
  r = run_command("WM_CLUSTER_TOKEN=0123456789abcdefgh " + wmd + store + "--cluster-id c1 --advertise ftp://x");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--advertise"), std::string::npos) << r.output;
  r = run_command(wmd + store + "--cluster-id c1 --cluster-token-file /nonexistent/token");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("cannot read"), std::string::npos) << r.output;
  r = run_command(wmd + store + "--advertise http://127.0.0.1:1");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("go with --cluster-id"), std::string::npos) << r.output;
}

TEST(ClusterStartTest, ANodeThatIsNoClustersAnswersTheStatus404) {
  TempDir dir;
  WmdProcess single({"--db", (dir.path() / "x.db").string(), "--port", "0", "--rules", WM_RULES_DIR});
  const auto r = raw_request(single.port(), http::verb::get, "/api/v1/cluster", {{"Host", "127.0.0.1"}});
  EXPECT_EQ(r.result_int(), 404u);
  EXPECT_NE(r.body().find("not_a_cluster"), std::string::npos) << r.body();
}

}  // namespace
}  // namespace wm::testing
