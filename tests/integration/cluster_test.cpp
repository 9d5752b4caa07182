// A cluster on loopback: three wmd nodes on one PostgreSQL, six maps, four robots per map posting scans with request
// ids through any node and retrying (another node, the same id) until answered, as the ROS bridge does. In each
// trial the owner of two maps is killed (kill -9) mid-ingest and started again; every few trials one is paused
// (SIGSTOP) past its lease instead, and resumed once its maps were taken over. Then, per map: every acknowledged
// scan is in the map once (none lost, none applied twice), and the map equals a single-node replay of its scans in
// the order they were committed (elements, objects, the decision log). Takeover times are printed, worst first.
// The grid's trims and grid-line extractions are off on both sides: they run on ticks whose place among concurrent
// robots' scans depends on timing (on a single node too), so only with them off is the decision log a function of
// the order of the scans alone.
//
// WM_CLUSTER_TRIALS=N sets the number of trials (default 50; CI runs 20, scripts/cluster_trials.sh N more).
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "e2e_fixture.h"
#include "logs/carmen_log_reader.h"
#include "logs/scan_body.h"
#include "support/postgres_server.h"

namespace wm::testing {
namespace {

namespace http = boost::beast::http;
using Clock = std::chrono::steady_clock;

constexpr int kNodes = 3;
constexpr int kRobotsPerMap = 4;
const std::vector<std::string> kMaps = {"m1", "m2", "m3", "m4", "m5", "m6"};
constexpr char kToken[] = "cluster-test-token-0123456789";

struct Reply {
  int status = 0;
  std::string body;
  std::string node;        // X-WM-Node: who served it
  std::int64_t epoch = 0;  // X-WM-Epoch: under which lease
  bool replayed = false;
};

std::optional<Reply> send(int port, http::verb verb, const std::string& target, const std::string& body,
                          const std::string& request_id, std::chrono::milliseconds timeout) {
  if (port <= 0) return std::nullopt;
  Headers headers{{"Host", "127.0.0.1"}};
  if (!request_id.empty()) headers.emplace_back("Idempotency-Key", request_id);
  try {
    const auto res = raw_request(port, verb, target, headers, body, timeout);
    Reply reply{static_cast<int>(res.result_int()), res.body(), std::string(res["X-WM-Node"]), 0,
                res["Idempotent-Replayed"] == "true"};
    if (!res["X-WM-Epoch"].empty()) reply.epoch = std::stoll(std::string(res["X-WM-Epoch"]));
    return reply;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// A robot's scan as wmctl replay posts it: the log's corrected pose, given σ 3 cm / 0.5° (good, not exact).
json scan_body(const fusion::LaserScan& scan, const std::string& source, double stamp) {
  auto body = logs::laser_scan_body(scan, source, stamp);
  const double sxy = 0.03, sth = 0.5 * M_PI / 180;
  body["pose_cov"] = {{sxy * sxy, 0, 0}, {0, sxy * sxy, 0}, {0, 0, sth * sth}};
  return body;
}

struct Ack {
  std::string map, key;
  Reply reply;
  Clock::time_point at;
};

class ClusterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    uri_ = postgres().uri();
    ::setenv("WM_CLUSTER_TOKEN", kToken, 1);
    logs::CarmenLogReader reader(std::filesystem::path(WM_SOURCE_DIR) /
                                 "tests/data/carmen/intel-corrected-excerpt.log.gz");
    while (auto s = reader.next()) scans_.push_back(s->scan);
    ASSERT_GE(scans_.size(), 30u);
    for (int i = 0; i < kNodes; ++i) start_node(i);
  }
  void TearDown() override {
    for (auto& node : nodes_)
      if (node) ::kill(node->pid(), SIGCONT);
    nodes_ = {};
    ::unsetenv("WM_CLUSTER_TOKEN");
  }

  static std::string node_id(int i) { return "node-" + std::to_string(i + 1); }
  void start_node(int i) {
    nodes_[i] = std::make_unique<WmdProcess>(std::vector<std::string>{
        "--store", uri_, "--cluster-id", "test", "--node-id", node_id(i), "--port", "0", "--rules", WM_RULES_DIR,
        "--no-shm", "--maps-dir", (dir_.path() / ("maps-" + std::to_string(i))).string(), "--grid-trim-every", "0",
        "--grid-extract-every", "0"});
    ports_[i] = nodes_[i]->port();
  }
  int live_port(std::size_t turn) const {
    for (int k = 0; k < kNodes; ++k) {
      const int port = ports_[(turn + k) % kNodes].load();
      if (port > 0) return port;
    }
    return -1;
  }
  json cluster_status(int port) {
    const auto r = send(port, http::verb::get, "/api/v1/cluster", "", "", std::chrono::seconds(5));
    if (!r || r->status != 200) return json::object();
    return json::parse(r->body);
  }
  // The maps each live node serves, as the database says (through node `port`).
  std::map<std::string, std::vector<std::string>> owners(int port) {
    std::map<std::string, std::vector<std::string>> result;
    const auto status = cluster_status(port);
    if (!status.contains("nodes")) return result;
    for (const auto& node : status["nodes"])
      if (node["alive"].get<bool>()) result[node["node"].get<std::string>()] = node["maps"];
    return result;
  }
  // Waits until every map is served by the node the database names, through node `port`; the time it took.
  std::optional<double> wait_served(const std::vector<std::string>& maps, const std::string& not_by, int port,
                                    Clock::time_point since, std::chrono::seconds limit) {
    std::set<std::string> waiting(maps.begin(), maps.end());
    while (Clock::now() - since < limit) {
      for (auto it = waiting.begin(); it != waiting.end();) {
        const auto r =
            send(port, http::verb::get, "/api/v1/maps/" + *it + "/health", "", "", std::chrono::milliseconds(500));
        if (r && r->status == 200 && !r->node.empty() && r->node != not_by)
          it = waiting.erase(it);
        else
          ++it;
      }
      if (waiting.empty()) return std::chrono::duration<double>(Clock::now() - since).count();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return std::nullopt;
  }

  void robot(const std::string& map, int index) {
    std::size_t turn = static_cast<std::size_t>(index);
    for (std::int64_t k = 0; !stop_; ++k) {
      const auto body =
          scan_body(scans_[(static_cast<std::size_t>(index) * 11 + static_cast<std::size_t>(k)) % scans_.size()],
                    map + "-robot-" + std::to_string(index), 0.1 * static_cast<double>(k + 1));
      const auto key = map + "-" + std::to_string(index) + "-" + std::to_string(k);
      const auto text = body.dump();
      {
        std::lock_guard lock(mutex_);
        bodies_[key] = text;
      }
      // Until answered: a request that got no answer may have been applied, and only its id keeps it once.
      const auto give_up = Clock::now() + std::chrono::minutes(1);
      for (;;) {
        if (stop_ && Clock::now() > give_up) {
          std::lock_guard lock(mutex_);
          refusals_.push_back(key + ": no answer in a minute");
          break;
        }
        const auto r = send(live_port(turn++), http::verb::post, "/api/v1/maps/" + map + "/scans", text, key,
                            std::chrono::seconds(8));
        if (r && r->status == 200) {
          std::lock_guard lock(mutex_);
          acks_.push_back({map, key, *r, Clock::now()});
          break;
        }
        if (r && r->status != 503) {
          std::lock_guard lock(mutex_);
          refusals_.push_back(key + ": " + std::to_string(r->status) + " " + r->body);
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(400));
    }
  }

  // One psql answer, rows of '|'-separated fields.
  std::vector<std::string> psql(const std::string& sql) {
    const auto r = run_command("psql \"" + uri_ + "\" -tAX -c \"" + sql + "\"");
    EXPECT_EQ(r.status, 0) << r.output;
    std::vector<std::string> rows;
    std::istringstream lines(r.output);
    for (std::string line; std::getline(lines, line);)
      if (!line.empty()) rows.push_back(line);
    return rows;
  }

  std::string uri_;
  TempDir dir_;
  std::vector<fusion::LaserScan> scans_;
  std::array<std::unique_ptr<WmdProcess>, kNodes> nodes_;
  std::array<std::atomic<int>, kNodes> ports_{};
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::map<std::string, std::string> bodies_;
  std::vector<Ack> acks_;
  std::vector<std::string> refusals_;
};

// What a map is, as the API gives it, for comparing two servers: its elements, objects and decisions without what
// says when or where it was served.
json map_state(int port, const std::string& prefix) {
  json state;
  for (const auto* part : {"elements", "objects"}) {
    const auto r = send(port, http::verb::get, prefix + "/" + part, "", "", std::chrono::seconds(60));
    EXPECT_TRUE(r && r->status == 200) << prefix << "/" << part;
    if (!r || r->status != 200) return state;
    auto value = json::parse(r->body);
    value.erase("version");
    value.erase("map_version");
    state[part] = std::move(value);
  }
  auto& decisions = state["decisions"] = json::array();
  for (std::int64_t since = 0;;) {
    const auto r = send(port, http::verb::get, prefix + "/decisions?limit=10000&since=" + std::to_string(since), "", "",
                        std::chrono::seconds(60));
    EXPECT_TRUE(r && r->status == 200) << prefix << "/decisions";
    if (!r || r->status != 200) return state;
    const auto page = json::parse(r->body);
    if (page["decisions"].empty()) break;
    for (const auto& d : page["decisions"]) decisions.push_back(d);
    since = page["next"].get<std::int64_t>();
  }
  return state;
}

TEST_F(ClusterTest, ADeadOwnersMapsAreTakenOverWithNoAcknowledgedScanLostOrAppliedTwice) {
  for (const auto& map : kMaps) {
    const auto r =
        send(ports_[0], http::verb::post, "/api/v1/maps", json{{"id", map}}.dump(), "", std::chrono::seconds(30));
    ASSERT_TRUE(r && r->status == 201) << (r ? r->body : "no answer");
  }
  // The maps spread: two per node.
  const auto spread_by = Clock::now() + std::chrono::seconds(30);
  for (;;) {
    const auto o = owners(ports_[1]);
    if (o.size() == kNodes && std::all_of(o.begin(), o.end(), [](const auto& n) { return n.second.size() == 2; }))
      break;
    ASSERT_LT(Clock::now(), spread_by) << cluster_status(ports_[1]).dump();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }

  std::vector<std::thread> robots;
  // The robots end with the test, a failed assertion included (each finishes the scan it is sending, or gives up on
  // it after a minute).
  struct JoinRobots {
    std::atomic<bool>& stop;
    std::vector<std::thread>& robots;
    ~JoinRobots() {
      stop = true;
      for (auto& t : robots)
        if (t.joinable()) t.join();
    }
  } join_robots{stop_, robots};
  for (const auto& map : kMaps)
    for (int r = 0; r < kRobotsPerMap; ++r) robots.emplace_back([this, map, r] { robot(map, r); });

  const int trials = std::getenv("WM_CLUSTER_TRIALS") ? std::atoi(std::getenv("WM_CLUSTER_TRIALS")) : 50;
  if (trials == 0) std::this_thread::sleep_for(std::chrono::seconds(10));  // ingest alone
  std::vector<double> takeovers;
  int paused_trials = 0, fenced_violations = 0;
  for (int trial = 0; trial < trials; ++trial) {
    std::this_thread::sleep_for(std::chrono::milliseconds(700));  // ingest runs on every node
    // The owner of the most maps (two or more) goes.
    int victim = -1;
    std::vector<std::string> its_maps;
    for (int wait = 0; wait < 100 && victim < 0; ++wait) {
      const auto o = owners(ports_[(trial + 1) % kNodes]);
      for (int i = 0; i < kNodes; ++i) {
        const auto found = o.find(node_id(i));
        if (found != o.end() && found->second.size() >= 2 && (victim < 0 || found->second.size() > its_maps.size())) {
          victim = i;
          its_maps = found->second;
        }
      }
      if (victim < 0) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    ASSERT_GE(victim, 0) << "no node serves two maps: " << cluster_status(ports_[0]).dump();
    const int witness = (victim + 1) % kNodes;
    const bool pause = trial % 10 == 9;
    if (!pause) {
      ports_[victim] = -1;
      const auto killed_at = Clock::now();
      nodes_[victim]->crash();
      const auto took = wait_served(its_maps, node_id(victim), ports_[witness], killed_at, std::chrono::seconds(20));
      ASSERT_TRUE(took) << "trial " << trial << ": " << node_id(victim) << "'s maps not taken over in 20 s";
      takeovers.push_back(*took);
      start_node(victim);
      continue;
    }
    // Paused past its lease: its maps are taken over; resumed, it commits nothing under its old leases.
    ++paused_trials;
    std::map<std::string, std::int64_t> old_epochs;
    for (const auto& lease : cluster_status(ports_[witness])["leases"])
      old_epochs[lease["map"].get<std::string>()] = lease["epoch"].get<std::int64_t>();
    const auto paused_at = Clock::now();
    ::kill(nodes_[victim]->pid(), SIGSTOP);
    const auto took = wait_served(its_maps, node_id(victim), ports_[witness], paused_at, std::chrono::seconds(20));
    ASSERT_TRUE(took) << "trial " << trial << ": a paused node's maps were not taken over";
    takeovers.push_back(*took);
    const auto resumed_at = Clock::now();
    ::kill(nodes_[victim]->pid(), SIGCONT);
    std::this_thread::sleep_for(std::chrono::seconds(2));
    std::lock_guard lock(mutex_);
    for (const auto& ack : acks_)
      if (ack.at > resumed_at && ack.reply.node == node_id(victim) && !ack.reply.replayed &&
          old_epochs.count(ack.map) && ack.reply.epoch <= old_epochs[ack.map]) {
        ++fenced_violations;
        ADD_FAILURE() << "resumed " << node_id(victim) << " committed " << ack.key << " at old epoch "
                      << ack.reply.epoch;
      }
  }
  stop_ = true;
  for (auto& t : robots) t.join();
  robots.clear();

  std::sort(takeovers.rbegin(), takeovers.rend());
  if (!takeovers.empty()) {
    std::printf("cluster: %d trials (%d paused), %zu scans acknowledged; takeover worst %.2f s, median %.2f s\n",
                trials, paused_trials, acks_.size(), takeovers.front(), takeovers[takeovers.size() / 2]);
    EXPECT_LE(takeovers.front(), 5.0) << "takeover within 5 s";
  }
  EXPECT_EQ(fenced_violations, 0);
  EXPECT_TRUE(refusals_.empty()) << refusals_.front();

  // Per map: every acknowledged scan once; the map as a single node makes it from the same scans in commit order.
  std::size_t compared = 0;
  for (const auto& map : kMaps) {
    const auto schema = "map_" + map;
    std::vector<std::string> committed;
    for (const auto& row : psql("SELECT request_id FROM " + schema + ".requests ORDER BY lines_seq NULLS LAST, seq"))
      committed.push_back(row);
    const std::set<std::string> committed_set(committed.begin(), committed.end());
    EXPECT_EQ(committed_set.size(), committed.size()) << map;
    for (const auto& ack : acks_)
      if (ack.map == map) {
        EXPECT_TRUE(committed_set.count(ack.key)) << "acknowledged and lost: " << ack.key;
      }
    EXPECT_TRUE(psql("SELECT observer, stamp FROM " + schema + ".scans GROUP BY 1, 2 HAVING count(*) > 1").empty())
        << map << ": a scan applied twice";
    EXPECT_EQ(psql("SELECT count(*) FROM " + schema + ".scans").at(0), std::to_string(committed.size())) << map;

    // The single-node replay.
    TempDir single_dir;
    WmdProcess single({"--db", (single_dir.path() / "single.db").string(), "--port", "0", "--rules", WM_RULES_DIR,
                       "--no-shm", "--grid-trim-every", "0", "--grid-extract-every", "0"});
    for (const auto& key : committed) {
      const auto r =
          send(single.port(), http::verb::post, "/api/v1/scans", bodies_.at(key), key, std::chrono::seconds(30));
      ASSERT_TRUE(r && r->status == 200) << key;
    }
    const auto cluster_map = map_state(live_port(0), "/api/v1/maps/" + map);
    const auto single_map = map_state(single.port(), "/api/v1");
    const auto diff = json::diff(single_map, cluster_map);
    if (std::getenv("WM_CLUSTER_DUMP")) {
      std::ofstream(std::string(std::getenv("WM_CLUSTER_DUMP")) + "/" + map + "-cluster.json") << cluster_map.dump(1);
      std::ofstream(std::string(std::getenv("WM_CLUSTER_DUMP")) + "/" + map + "-single.json") << single_map.dump(1);
    }
    EXPECT_TRUE(diff.empty()) << map << ": the cluster's map differs from a single node's replay of "
                              << committed.size() << " scans in " << diff.size()
                              << " places, first: " << (diff.empty() ? json() : diff[0]).dump().substr(0, 600);
    compared += committed.size();
  }
  std::printf("cluster: %zu committed scans compared with single-node replays\n", compared);
}

}  // namespace
}  // namespace wm::testing
