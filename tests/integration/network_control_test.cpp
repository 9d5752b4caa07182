// The processing network controlled while wmd runs, over real HTTP: subtasks started and stopped, a component's
// parameters changed (PUT /api/v1/network/...), hostile bodies and callers, and the grid line extractor switched off
// and on again during a replay of the Intel log.
#include <algorithm>
#include <atomic>
#include <boost/beast/http.hpp>
#include <chrono>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "e2e_fixture.h"
#include "logs/carmen_log_reader.h"
#include "logs/scan_body.h"

namespace wm::testing {
namespace {

namespace bhttp = boost::beast::http;

constexpr const char* kToken = "s3cret";
const Headers kAuth = {{"Authorization", std::string("Bearer ") + kToken}};

json find_named(const json& list, const std::string& key, const std::string& name) {
  for (const auto& item : list)
    if (item[key] == name) return item;
  return nullptr;
}

class NetworkControlTest : public ServerFixture {
 protected:
  void SetUp() override {
    extra_args_ = {"--token", kToken, "--grid-extract-every", "20", "--max-body-bytes", "65536"};
    ServerFixture::SetUp();
  }
  // A PUT with the token: status and JSON body.
  std::pair<int, json> put(const std::string& target, const std::string& body, const Headers& headers = kAuth) {
    const auto r = raw_request(server_->port(), bhttp::verb::put, target, headers, body);
    return {r.result_int(), json::parse(r.body(), nullptr, false)};
  }
  json network() { return get_json("/api/v1/network"); }
  json function_stats(const std::string& component, const std::string& function) {
    const auto n = network();  // kept: a range over a member of a temporary would dangle
    for (const auto& f : n["functions"])
      if (f["component"] == component && f["function"] == function) return f;
    return nullptr;
  }
  json port_stats(const std::string& component, const std::string& port) {
    const auto n = network();
    for (const auto& p : n["ports"])
      if (p["component"] == component && p["port"] == port) return p;
    return nullptr;
  }
  // The map's elements of origin grid, by id.
  std::set<std::string> grid_elements() {
    std::set<std::string> ids;
    const auto map = get_json("/api/v1/map");
    for (const auto& e : map["elements"])
      if (e["origin"] == "grid") ids.insert(e["id"].get<std::string>());
    return ids;
  }
  // Decisions on the grid line extractor's observations logged after `since` (seq); the grid trim's observations
  // are of origin grid too, but come from another observer.
  int grid_decisions_since(std::int64_t since) {
    int count = 0;
    for (;;) {
      const auto page = get_json("/api/v1/decisions?since=" + std::to_string(since) + "&limit=1000");
      for (const auto& d : page["decisions"])
        if (d["origin"] == "grid" && d["observer"] == "grid-extractor") ++count;
      if (page["decisions"].empty() || page["next"].get<std::int64_t>() == since) return count;
      since = page["next"].get<std::int64_t>();
    }
  }
  std::int64_t last_decision_seq() { return get_json("/api/v1/health")["last_decision_seq"].get<std::int64_t>(); }
  // The extractor's activation count, once it stops moving (an activation is counted when it returns, which may be
  // just after the answer it let go).
  std::uint64_t settled_extractions() {
    std::uint64_t last = ~std::uint64_t{0};
    for (int i = 0; i < 100; ++i) {
      const auto now = function_stats("grid_lines", "extract")["activations"].get<std::uint64_t>();
      if (now == last) return now;
      last = now;
      std::this_thread::sleep_for(std::chrono::milliseconds(30));
    }
    return last;
  }
};

TEST_F(NetworkControlTest, TheNetworkShowsSubtasksAndParams) {
  const auto n = network();
  ASSERT_EQ(n["subtasks"].size(), 1u) << n.dump();
  EXPECT_EQ(n["subtasks"][0], json({{"name", "grid-lines"}, {"running", true}, {"components", {"grid_lines"}}}));
  const auto grid = find_named(n["components"], "name", "grid");
  EXPECT_EQ(grid["kind"], "grid");
  EXPECT_EQ(grid["params"]["extract_every"], "20");  // the command line's default, as the grid holds it
  const auto& settable = grid["settable"];
  EXPECT_NE(std::find(settable.begin(), settable.end(), "extract_every"), settable.end()) << grid.dump();
  EXPECT_TRUE(grid["subtask"].is_null());
  EXPECT_EQ(find_named(n["components"], "name", "store")["params"]["max_batch"], "64");
  EXPECT_EQ(find_named(n["components"], "name", "grid_lines")["subtask"], "grid-lines");
}

TEST_F(NetworkControlTest, SubtasksAndParamsChangeWithTheTokenAndAnswerTheNewState) {
  auto [status, answer] = put("/api/v1/network/subtasks/grid-lines", R"({"running": false})");
  ASSERT_EQ(status, 200) << answer.dump();
  EXPECT_EQ(answer["subtasks"][0]["running"], false);
  EXPECT_EQ(find_named(answer["components"], "name", "grid_lines")["running"], false);
  EXPECT_EQ(network()["subtasks"][0]["running"], false);
  std::tie(status, answer) = put("/api/v1/network/subtasks/grid-lines", R"({"running": true})");
  ASSERT_EQ(status, 200);
  EXPECT_EQ(answer["subtasks"][0]["running"], true);

  std::tie(status, answer) = put("/api/v1/network/components/grid/params", R"({"extract_every": 5})");
  ASSERT_EQ(status, 200) << answer.dump();
  EXPECT_EQ(find_named(answer["components"], "name", "grid")["params"]["extract_every"], "5");
  std::tie(status, answer) = put("/api/v1/network/components/grid/params", R"({"extract_every": "0"})");
  ASSERT_EQ(status, 200) << answer.dump();
  EXPECT_EQ(find_named(network()["components"], "name", "grid")["params"]["extract_every"], "0");
}

TEST_F(NetworkControlTest, HostileCallsAreRefusedAndChangeNothing) {
  const auto extract_every = [&] {
    return find_named(network()["components"], "name", "grid")["params"]["extract_every"].get<std::string>();
  };
  // No token, a wrong one: 401.
  EXPECT_EQ(put("/api/v1/network/subtasks/grid-lines", R"({"running": false})", {}).first, 401);
  EXPECT_EQ(put("/api/v1/network/subtasks/grid-lines", R"({"running": false})", {{"Authorization", "Bearer x"}}).first,
            401);
  EXPECT_EQ(put("/api/v1/network/components/grid/params", R"({"extract_every": 1})", {}).first, 401);
  // A cross-site page: 403.
  auto headers = kAuth;
  headers.emplace_back("Origin", "http://attacker.example");
  EXPECT_EQ(put("/api/v1/network/subtasks/grid-lines", R"({"running": false})", headers).first, 403);
  EXPECT_EQ(network()["subtasks"][0]["running"], true);

  // Unknown names: 404.
  auto [status, answer] = put("/api/v1/network/subtasks/nothing", R"({"running": false})");
  EXPECT_EQ(status, 404) << answer.dump();
  EXPECT_EQ(answer["error"], "not_found");
  EXPECT_EQ(put("/api/v1/network/components/nobody/params", R"({"extract_every": 1})").first, 404);

  // Wrong types in the subtask's body: 400.
  for (const std::string body : {R"({"running": "false"})", R"({"running": 0})", R"({"running": null})", R"({})",
                                 R"({"running": true, "extra": 1})", R"([true])", R"(not json)"}) {
    std::tie(status, answer) = put("/api/v1/network/subtasks/grid-lines", body);
    EXPECT_EQ(status, 400) << body << " → " << answer.dump();
  }
  // A value of a type no task file gives (an array, an object, null): 400.
  for (const std::string body :
       {R"({"extract_every": [1]})", R"({"extract_every": {"a": 1}})", R"({"extract_every": null})"}) {
    std::tie(status, answer) = put("/api/v1/network/components/grid/params", body);
    EXPECT_EQ(status, 400) << body << " → " << answer.dump();
  }
  // Bad values: 422 with the task file's message, and nothing changes.
  const std::string message = "component 'grid' (grid): parameter 'extract_every' must be a number in [0, 1e+09], not ";
  for (const auto& [body, shown] :
       std::vector<std::pair<std::string, std::string>>{{R"({"extract_every": -1})", "'-1'"},
                                                        {R"({"extract_every": "NaN"})", "'NaN'"},
                                                        {R"({"extract_every": "inf"})", "'inf'"},
                                                        {R"({"extract_every": 1e12})", "'1000000000000.0'"},
                                                        {R"({"extract_every": "12abc"})", "'12abc'"},
                                                        {R"({"extract_every": true})", ""}}) {
    std::tie(status, answer) = put("/api/v1/network/components/grid/params", body);
    EXPECT_EQ(status, 422) << body << " → " << answer.dump();
    if (!shown.empty()) {
      EXPECT_EQ(answer["detail"], message + shown) << body;
    }
  }
  std::tie(status, answer) = put("/api/v1/network/components/grid/params", R"({"extract_every": 5, "speed": 2})");
  EXPECT_EQ(status, 422);
  const auto detail = answer["detail"].get<std::string>();
  EXPECT_EQ(
      detail.rfind("component 'grid' (grid): parameter 'speed' cannot change while the network runs (these can: ", 0),
      0u)
      << detail;
  EXPECT_NE(detail.find("extract_every"), std::string::npos) << detail;
  std::tie(status, answer) = put("/api/v1/network/components/store/params", R"({"max_batch": 1})");
  EXPECT_EQ(status, 422);
  EXPECT_EQ(put("/api/v1/network/components/grid/params", R"({})").first, 422);
  // A literal NaN is not JSON.
  EXPECT_EQ(put("/api/v1/network/components/grid/params", R"({"extract_every": NaN})").first, 400);
  // Larger than --max-body-bytes: 413.
  const std::string huge = R"({"extract_every": ")" + std::string(70000, '1') + R"("})";
  EXPECT_EQ(put("/api/v1/network/components/grid/params", huge).first, 413);
  EXPECT_EQ(extract_every(), "20");
}

// A task file whose subtask would stop what the HTTP writes or the store need, or that leaves a tie unordered, is
// refused at start with the file, the line where it can, and the reason.
TEST(NetworkTaskFileTest, SubtasksThatWouldStopRequestsAndUnorderedTiesAreRefusedAtStart) {
  TempDir dir;
  const auto base = slurp(std::string(WM_SOURCE_DIR) + "/networks/default.yaml");
  ASSERT_NE(base.find("grid-lines: {components: [grid_lines], running: true}"), std::string::npos);
  const auto refused = [&](const std::string& yaml) {
    const auto file = dir.path() / "net.yaml";
    std::ofstream(file) << yaml;
    const auto r = run_command(std::string(WM_WMD_PATH) + " --db " + (dir.path() / "wm.db").string() +
                               " --port 0 --rules " + WM_RULES_DIR + " --network " + file.string() + " 2>&1");
    EXPECT_NE(r.status, 0) << r.output;
    return r.output;
  };
  auto with = [&](const std::string& from, const std::string& to) {
    auto text = base;
    text.replace(text.find(from), from.size(), to);
    return text;
  };
  auto output = refused(with("components: [grid_lines]", "components: [grid_lines, matcher]"));
  EXPECT_NE(output.find("net.yaml: subtask 'grid-lines': component 'matcher' takes values from outside the network "
                        "on 'laser' (the HTTP writes): it cannot be stopped"),
            std::string::npos)
      << output;
  output = refused(with("components: [grid_lines]", "components: [store]"));
  EXPECT_NE(output.find("net.yaml: subtask 'grid-lines': component 'store' takes every value on 'in' (a fifo: "
                        "requests wait for them): only components whose inputs keep the latest value can be stopped"),
            std::string::npos)
      << output;
  output = refused(with("grid: {kind: grid}", "grid: {kind: grid, priorities: [laser_and_sonar]}"));
  EXPECT_NE(output.find("net.yaml: component 'grid': functions 'laser' and 'sonar' both depend on 1 ports: give them "
                        "a relative priority (priorities: [laser, sonar] or the reverse)"),
            std::string::npos)
      << output;
  output = refused(with("running: true", "running: perhaps"));
  EXPECT_NE(output.find("net.yaml:12: subtask 'grid-lines': running must be true or false"), std::string::npos)
      << output;
}

// wmctl network subtask NAME on|off and wmctl network set COMPONENT key=value...
TEST_F(NetworkControlTest, WmctlSwitchesSubtasksAndSetsParams) {
  const auto with_token = std::string("--token ") + kToken + " ";
  auto r = run_command(wmctl(server_->url(), with_token + "network subtask grid-lines off"));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("subtask grid-lines: off, components grid_lines"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("component grid_lines (grid_lines) [stopped]"), std::string::npos) << r.output;
  EXPECT_EQ(network()["subtasks"][0]["running"], false);
  r = run_command(wmctl(server_->url(), with_token + "network subtask grid-lines on"));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("subtask grid-lines: on"), std::string::npos) << r.output;

  r = run_command(wmctl(server_->url(), with_token + "network set grid extract_every=7"));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("component grid (grid) extract_every=7"), std::string::npos) << r.output;
  r = run_command(wmctl(server_->url(), with_token + "--json network set grid extract_every=9"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(find_named(json::parse(r.output)["components"], "name", "grid")["params"]["extract_every"], "9");
  r = run_command(wmctl(server_->url(), "network"));
  EXPECT_NE(r.output.find("component grid (grid) extract_every=9"), std::string::npos) << r.output;

  // Refusals: the server's reason and exit 1; usage errors exit 2.
  r = run_command(wmctl(server_->url(), with_token + "network set grid extract_every=soon"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("422 rejected: component 'grid' (grid): parameter 'extract_every' must be a number"),
            std::string::npos)
      << r.output;
  r = run_command(wmctl(server_->url(), "network subtask grid-lines off"));  // no token
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("401"), std::string::npos) << r.output;
  r = run_command(wmctl(server_->url(), with_token + "network subtask nothing off"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("404"), std::string::npos) << r.output;
  r = run_command(wmctl(server_->url(), with_token + "network subtask grid-lines maybe"));
  EXPECT_EQ(r.status, 2) << r.output;
  r = run_command(wmctl(server_->url(), with_token + "network set grid extract_every"));
  EXPECT_EQ(r.status, 2) << r.output;
  r = run_command(wmctl(server_->url(), with_token + "network set grid"));
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_EQ(find_named(network()["components"], "name", "grid")["params"]["extract_every"], "9");
  EXPECT_EQ(network()["subtasks"][0]["running"], true);
}

// Toggling the subtask and changing the extractor's period while scans stream in from several writers: every scan
// is answered 200, none waits for a stopped component, and the counts add up.
TEST_F(NetworkControlTest, ConcurrentTogglesWhileScansStream) {
  const auto log = real_data("carmen/intel-corrected.log.gz", "carmen/intel-corrected.log.gz");
  logs::CarmenLogReader reader(log);
  std::vector<std::string> bodies;
  while (auto s = reader.next()) {
    bodies.push_back(logs::laser_scan_body(s->scan, "intel", s->timestamp_s).dump());
    if (bodies.size() == 240) break;
  }
  ASSERT_GE(bodies.size(), 100u);
  std::atomic<int> answered{0}, refused{0};
  std::atomic<bool> done{false};
  std::vector<std::thread> writers;
  for (int w = 0; w < 2; ++w)
    writers.emplace_back([&, w] {
      client::HttpClient client(server_->url());
      for (std::size_t i = static_cast<std::size_t>(w); i < bodies.size(); i += 2) {
        const auto r = client.request("POST", "/api/v1/scans", bodies[i], "application/json", kToken);
        (r.status == 200 ? answered : refused)++;
      }
    });
  std::atomic<int> toggles{0}, toggle_errors{0};
  std::thread toggler([&] {
    client::HttpClient client(server_->url());
    for (int i = 0; !done; ++i) {
      const json body = {{"running", i % 2 == 1}};
      auto r = client.request("PUT", "/api/v1/network/subtasks/grid-lines", body.dump(), "application/json", kToken);
      if (r.status != 200) ++toggle_errors;
      r = client.request("PUT", "/api/v1/network/components/grid/params", json({{"extract_every", 5 + i % 7}}).dump(),
                         "application/json", kToken);
      if (r.status != 200) ++toggle_errors;
      ++toggles;
    }
  });
  for (auto& w : writers) w.join();
  done = true;
  toggler.join();
  EXPECT_EQ(answered.load(), static_cast<int>(bodies.size()));
  EXPECT_EQ(refused.load(), 0);
  EXPECT_EQ(toggle_errors.load(), 0);
  EXPECT_GE(toggles.load(), 1);
  // Every tick the grid sent went to the extractor or was dropped while it was stopped.
  const auto tick = port_stats("grid_lines", "tick");
  EXPECT_GE(tick["pushed"].get<std::uint64_t>() + tick["dropped_stopped"].get<std::uint64_t>(), 1u) << tick.dump();
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
}

// The end-to-end check: during a replay of the Intel log the grid line extractor (every 20 scans) is switched off,
// and no observation of origin grid is decided while it is off, its activations stand still and its ticks are
// counted as dropped; switched on again, it resumes.
TEST_F(NetworkControlTest, SwitchingTheGridLinesSubtaskOffStopsGridElementsAndOnResumesThem) {
  const auto log = real_data("carmen/intel-corrected.log.gz", "carmen/intel-corrected.log.gz");
  logs::CarmenLogReader reader(log);
  const auto post_scans = [&](int count) {
    int posted = 0;
    while (posted < count) {
      const auto s = reader.next();
      if (!s) break;
      const auto r =
          client_->request("POST", "/api/v1/scans", logs::laser_scan_body(s->scan, "intel", s->timestamp_s).dump(),
                           "application/json", kToken);
      if (r.status != 200) {
        ADD_FAILURE() << "scan " << posted << ": " << r.status << " " << r.body;
        return posted;
      }
      ++posted;
    }
    return posted;
  };
  const auto send_with_token = [&](const std::string& target, const json& body) {
    const auto r = client_->request("PUT", target, body.dump(), "application/json", kToken);
    EXPECT_EQ(r.status, 200) << r.body;
    return json::parse(r.body);
  };

  // On: 200 scans, 10 extractions.
  ASSERT_EQ(post_scans(200), 200);
  const auto extractions_on = settled_extractions();
  const auto grid_on = grid_elements();
  const auto decisions_on = grid_decisions_since(0);
  EXPECT_EQ(extractions_on, 10u);
  EXPECT_GT(grid_on.size(), 0u) << "the extractor found no line in 200 Intel scans";
  EXPECT_GT(decisions_on, 0);
  std::cerr << "[figures] on: " << extractions_on << " extractions, " << grid_on.size() << " grid elements, "
            << decisions_on << " grid decisions\n";

  // Off: 200 more scans, 10 ticks dropped, no extraction, nothing of origin grid decided.
  const auto off = send_with_token("/api/v1/network/subtasks/grid-lines", {{"running", false}});
  EXPECT_EQ(off["subtasks"][0]["running"], false);
  const auto seq_off = last_decision_seq();
  const auto dropped_before = port_stats("grid_lines", "tick")["dropped_stopped"].get<std::uint64_t>();
  ASSERT_EQ(post_scans(200), 200);
  const auto extractions_off = settled_extractions();
  const auto grid_off = grid_elements();
  EXPECT_EQ(extractions_off, extractions_on);
  EXPECT_EQ(grid_decisions_since(seq_off), 0);
  EXPECT_EQ(port_stats("grid_lines", "tick")["dropped_stopped"].get<std::uint64_t>() - dropped_before, 10u);
  for (const auto& id : grid_off) EXPECT_TRUE(grid_on.count(id)) << "new grid element " << id << " while off";
  std::cerr << "[figures] off: " << extractions_off << " extractions, " << grid_off.size() << " grid elements, "
            << grid_decisions_since(seq_off) << " grid decisions since switched off\n";

  // On again, every 10 scans: 200 scans, 20 extractions, new grid elements.
  send_with_token("/api/v1/network/components/grid/params", {{"extract_every", 10}});
  const auto on = send_with_token("/api/v1/network/subtasks/grid-lines", {{"running", true}});
  EXPECT_EQ(on["subtasks"][0]["running"], true);
  const auto seq_on = last_decision_seq();
  ASSERT_EQ(post_scans(200), 200);
  const auto extractions_again = settled_extractions();
  const auto grid_again = grid_elements();
  EXPECT_EQ(extractions_again, extractions_off + 20);
  const auto decisions_again = grid_decisions_since(seq_on);
  EXPECT_GT(decisions_again, 0);
  std::size_t fresh = 0;
  for (const auto& id : grid_again) fresh += grid_off.count(id) ? 0 : 1;
  EXPECT_GT(fresh, 0u) << "no new grid element after switching the extractor on again";
  std::cerr << "[figures] on again: " << extractions_again << " extractions, " << grid_again.size()
            << " grid elements (" << fresh << " new), " << decisions_again << " grid decisions\n";
}

}  // namespace
}  // namespace wm::testing
