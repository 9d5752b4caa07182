// The HTTP edge under hostile input: JSON nesting, invalid UTF-8, Host and Origin checks, the
// events WebSocket's auth, the token scheme, dry runs without a token, non-loopback binds, bounded query
// answers, handlers off the I/O threads and the accept loop's back-off. Each test replays the reproducer.
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
namespace net = boost::asio;
namespace websocket = boost::beast::websocket;

struct Upgrade {
  int status = 0;           // 101 when upgraded
  std::string body;         // the refusal's JSON
  std::string first_event;  // the first message after an upgrade
};

// A WebSocket handshake on `target` with extra headers: first as a plain request (Beast's client does not
// hand back a refusal's status and body), then, when that upgraded, with Beast's client to read the hello.
Upgrade ws_upgrade(int port, const std::string& target, const Headers& headers, const std::string& host = "") {
  Headers upgrade = headers;
  upgrade.insert(upgrade.end(), {{"Host", host.empty() ? "127.0.0.1:" + std::to_string(port) : host},
                                 {"Upgrade", "websocket"},
                                 {"Connection", "Upgrade"},
                                 {"Sec-WebSocket-Version", "13"},
                                 {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="}});
  const auto answer = raw_request(port, bhttp::verb::get, target, upgrade);
  if (answer.result_int() != 101) return {static_cast<int>(answer.result_int()), answer.body(), {}};
  net::io_context ioc;
  websocket::stream<beast::tcp_stream> ws(ioc);
  beast::get_lowest_layer(ws).connect(
      net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)));
  ws.set_option(websocket::stream_base::decorator([headers](websocket::request_type& req) {
    for (const auto& [name, value] : headers) req.set(name, value);
  }));
  websocket::response_type res;
  beast::error_code ec;
  ws.handshake(res, host.empty() ? "127.0.0.1:" + std::to_string(port) : host, target, ec);
  Upgrade u{static_cast<int>(res.result_int()), res.body(), {}};
  if (!ec) {
    beast::flat_buffer buffer;
    ws.read(buffer, ec);
    if (!ec) u.first_event = beast::buffers_to_string(buffer.data());
  }
  return u;
}

std::string nested_objects(std::size_t levels) {
  std::string text;
  text.reserve(levels * 6 + 1);
  for (std::size_t i = 0; i < levels; ++i) text += "{\"a\":";
  text += "1";
  text.append(levels, '}');
  return text;
}

json body_of(const std::string& text) { return json::parse(text, nullptr, false); }

class SecurityHttpTest : public ServerFixture {};

// Deep JSON cannot crash wmd: 100 000 nested objects in a PUT /api/v1/floorplan crashed it (SIGSEGV in nlohmann's
// recursive parse/copy). Every JSON body now goes through one nesting check first.
TEST_F(SecurityHttpTest, DeeplyNestedJsonIsRefusedWith400Everywhere) {
  const std::string deep = nested_objects(100000);
  const std::string deep_array = std::string(100000, '[') + std::string(100000, ']');
  const std::string envelope = R"({"import": {"format": "dxf", "data": "", "mapping": )";
  struct Case {
    const char* method;
    const char* target;
    std::string body;
    std::size_t refused_at;  // the byte of the 65th opening bracket
  };
  const std::vector<Case> cases = {
      {"PUT", "/api/v1/floorplan", deep, 64 * 5},
      {"PUT", "/api/v1/floorplan", deep_array, 64},  // a bare array is an AMRL vector map
      {"PUT", "/api/v1/floorplan", envelope + deep + "}}", envelope.size() + 62 * 5},
      {"POST", "/api/v1/primitives", deep, 64 * 5},
      {"POST", "/api/v1/scans", deep, 64 * 5},
      {"POST", "/api/v1/query", deep, 64 * 5},
  };
  for (const auto& c : cases) {
    const auto r = call(c.method, c.target, c.body);
    EXPECT_EQ(r.status, 400) << c.target << ": " << r.body.substr(0, 300);
    const auto answer = body_of(r.body);
    EXPECT_EQ(answer.value("error", ""), "bad_request") << r.body;
    EXPECT_EQ(answer.value("detail", ""), "JSON nested deeper than 64 levels at byte " + std::to_string(c.refused_at))
        << c.target;
  }
  // JSON text inside the import envelope reaches the AMRL importer's own check.
  const auto inner =
      call("PUT", "/api/v1/floorplan", json{{"import", {{"format", "amrl"}, {"data", deep_array}}}}.dump());
  EXPECT_EQ(inner.status, 400) << inner.body.substr(0, 300);
  EXPECT_EQ(body_of(inner.body).value("error", ""), "bad_floor_plan");
  EXPECT_NE(body_of(inner.body).value("detail", "").find("JSON nested deeper than 64 levels at byte 64"),
            std::string::npos)
      << inner.body;
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
  EXPECT_EQ(get_json("/api/v1/floorplan")["objects"].size(), 0u);
}

TEST_F(SecurityHttpTest, ADeeplyNestedFloorPlanFileIsRefusedAtStart) {
  const auto plan = dir_.path() / "deep.json";
  std::ofstream(plan) << nested_objects(100000);
  const auto r = run_command("timeout 60 " + std::string(WM_WMD_PATH) + " --db " + (dir_.path() / "x.db").string() +
                             " --port 0 --floorplan " + plan.string());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("JSON nested deeper than 64 levels"), std::string::npos) << r.output;
}

// Outside text is checked as UTF-8: invalid UTF-8 in YAML (or in a name given as a query parameter) answered 500
// (nlohmann type_error 316 when the plan was written); now 400 naming where.
TEST_F(SecurityHttpTest, InvalidUtf8IsRefusedWith400NamingTheField) {
  std::string yaml = slurp(std::filesystem::path(WM_SOURCE_DIR) / "tests/data/plans/rmf-office.building.yaml");
  const auto at = yaml.find("main_door");
  ASSERT_NE(at, std::string::npos);
  yaml.replace(at, 9, "main_d\xff\xfeoor");
  const auto line = 1 + std::count(yaml.begin(), yaml.begin() + static_cast<std::ptrdiff_t>(at), '\n');
  const auto r = call("PUT", "/api/v1/floorplan", yaml, "application/yaml");
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(body_of(r.body).value("error", ""), "bad_request") << r.body;
  EXPECT_EQ(body_of(r.body).value("detail", ""), "body: invalid UTF-8 at byte " + std::to_string(at + 6) + " (line " +
                                                     std::to_string(line) + "); YAML is UTF-8 text");

  const auto amrl = slurp(std::filesystem::path(WM_SOURCE_DIR) / "tests/data/plans/AHG2.vectormap.json");
  const auto named = call("PUT", "/api/v1/floorplan?name=pavilion%FF", amrl);
  EXPECT_EQ(named.status, 400) << named.body;
  EXPECT_EQ(body_of(named.body).value("detail", ""), "name: invalid UTF-8 at byte 8 of the query parameter");
  // The same plan with a valid name loads: the check refuses only what is broken.
  const auto good = call("PUT", "/api/v1/floorplan?name=pavill%C3%B3n", amrl);
  EXPECT_EQ(good.status, 200) << good.body.substr(0, 300);
  EXPECT_EQ(body_of(good.body).value("name", ""), "pavill\xc3\xb3n");
}

// Against DNS rebinding: with no token, a page of attacker.example re-resolved to 127.0.0.1 could
// write; every request's Host must be a loopback name, the bind address, an IP literal or --allowed-hosts.
TEST_F(SecurityHttpTest, HostHeaderIsCheckedOnEveryRequest) {
  const int port = server_->port();
  const auto p = ":" + std::to_string(port);
  const auto rebound =
      raw_request(port, bhttp::verb::put, "/api/v1/floorplan", {{"Host", "attacker.example" + p}}, lab_plan().dump());
  EXPECT_EQ(rebound.result_int(), 421) << rebound.body();
  EXPECT_EQ(body_of(rebound.body()).value("error", ""), "misdirected_request");
  EXPECT_EQ(raw_request(port, bhttp::verb::get, "/api/v1/map", {{"Host", "attacker.example" + p}}).result_int(), 421);
  EXPECT_EQ(raw_request(port, bhttp::verb::get, "/api/v1/health", {{"Host", "ATTACKER.example"}}).result_int(), 421);
  EXPECT_EQ(get_json("/api/v1/floorplan")["objects"].size(), 0u) << "nothing written";
  for (const auto& host :
       std::vector<std::string>{"localhost" + p, "LocalHost", "127.0.0.1" + p, "[::1]" + p, "10.1.2.3" + p})
    EXPECT_EQ(raw_request(port, bhttp::verb::get, "/api/v1/health", {{"Host", host}}).result_int(), 200) << host;

  extra_args_ = {"--allowed-hosts", "wm.example,robots.lan"};
  restart();
  EXPECT_EQ(
      raw_request(server_->port(), bhttp::verb::get, "/api/v1/health", {{"Host", "wm.example:8080"}}).result_int(),
      200);
  EXPECT_EQ(raw_request(server_->port(), bhttp::verb::get, "/api/v1/health", {{"Host", "robots.lan"}}).result_int(),
            200);
  EXPECT_EQ(raw_request(server_->port(), bhttp::verb::get, "/api/v1/health", {{"Host", "evil.lan"}}).result_int(), 421);
}

// Writes from another site's page (a simple cross-site POST needs no preflight) are refused by Origin.
TEST_F(SecurityHttpTest, WritesFromAnotherOriginAreRefused) {
  const int port = server_->port();
  const auto self = "127.0.0.1:" + std::to_string(port);
  const auto primitive = R"({"segments": [{"p0": [1, 1], "p1": [2, 1]}]})";
  const auto cross = raw_request(port, bhttp::verb::post, "/api/v1/primitives",
                                 {{"Host", self}, {"Origin", "http://attacker.example"}}, primitive);
  EXPECT_EQ(cross.result_int(), 403) << cross.body();
  EXPECT_EQ(body_of(cross.body()).value("error", ""), "forbidden_origin");
  EXPECT_EQ(get_json("/api/v1/health")["last_decision_seq"], 0);
  const auto same = raw_request(port, bhttp::verb::post, "/api/v1/primitives",
                                {{"Host", self}, {"Origin", "http://" + self}}, primitive);
  EXPECT_EQ(same.result_int(), 200) << same.body();
  // Reading from another origin stays possible (the viewer's ?api= development mode).
  EXPECT_EQ(raw_request(port, bhttp::verb::get, "/api/v1/map", {{"Host", self}, {"Origin", "http://attacker.example"}})
                .result_int(),
            200);
}

// The events WebSocket is authorised like a write: it upgraded with no token, a wrong token, or Origin
// attacker.example.
TEST_F(SecurityHttpTest, EventsWebSocketNeedsTheTokenAndTheServersOrigin) {
  extra_args_ = {"--token", "s3cret", "--allowed-origins", "http://viewer.example:3000"};
  restart();
  const int port = server_->port();
  const auto self = "http://127.0.0.1:" + std::to_string(port);

  const auto anonymous = ws_upgrade(port, "/api/v1/events", {});
  EXPECT_EQ(anonymous.status, 401) << anonymous.body;
  EXPECT_EQ(body_of(anonymous.body).value("error", ""), "unauthorized");
  EXPECT_EQ(ws_upgrade(port, "/api/v1/events", {{"Authorization", "Bearer wrong"}}).status, 401);
  EXPECT_EQ(ws_upgrade(port, "/api/v1/events?token=wrong", {}).status, 401);
  const auto hijack = ws_upgrade(port, "/api/v1/events?token=s3cret", {{"Origin", "http://attacker.example"}});
  EXPECT_EQ(hijack.status, 403) << hijack.body;
  EXPECT_EQ(body_of(hijack.body).value("error", ""), "forbidden_origin");
  EXPECT_EQ(ws_upgrade(port, "/api/v1/events?token=s3cret", {}, "attacker.example").status, 421);

  const auto header = ws_upgrade(port, "/api/v1/events", {{"Authorization", "bearer s3cret"}});
  EXPECT_EQ(header.status, 101);
  EXPECT_EQ(body_of(header.first_event).value("type", ""), "hello") << header.first_event;
  const auto browser = ws_upgrade(port, "/api/v1/events?token=s3cret", {{"Origin", self}});
  EXPECT_EQ(browser.status, 101);
  EXPECT_EQ(body_of(browser.first_event).value("type", ""), "hello");
  EXPECT_EQ(ws_upgrade(port, "/api/v1/events?token=s3cret", {{"Origin", "http://viewer.example:3000"}}).status, 101);
}

TEST_F(SecurityHttpTest, EventsWebSocketWithoutATokenStillChecksOrigin) {
  const int port = server_->port();
  EXPECT_EQ(ws_upgrade(port, "/api/v1/events", {{"Origin", "http://attacker.example"}}).status, 403);
  EXPECT_EQ(ws_upgrade(port, "/api/v1/events", {{"Origin", "http://127.0.0.1:" + std::to_string(port)}}).status, 101);
  EXPECT_EQ(ws_upgrade(port, "/api/v1/events", {}).status, 101);
}

// The token's scheme is matched as RFC 7235 says, case-insensitively: "bearer" in lower case was refused.
TEST_F(SecurityHttpTest, BearerSchemeIsCaseInsensitive) {
  extra_args_ = {"--token", "s3cret"};
  restart();
  const int port = server_->port();
  const auto host = "127.0.0.1:" + std::to_string(port);
  const auto status = [&](const std::string& authorization) {
    Headers headers{{"Host", host}};
    if (!authorization.empty()) headers.emplace_back("Authorization", authorization);
    return raw_request(port, bhttp::verb::post, "/api/v1/rules/reload", headers, "{}").result_int();
  };
  EXPECT_EQ(status("Bearer s3cret"), 200);
  EXPECT_EQ(status("bearer s3cret"), 200);
  EXPECT_EQ(status("BEARER   s3cret"), 200);
  EXPECT_EQ(status("Bearer s3cre"), 401);
  EXPECT_EQ(status("Bearer s3cret2"), 401);
  EXPECT_EQ(status("Basic czNjcmV0"), 401);
  EXPECT_EQ(status("Bearers3cret"), 401);
  EXPECT_EQ(status(""), 401);
}

// Dry runs are writes of code: a dry run loads rule text, so it needs the token; with none configured it is
// refused unless wmd was started with --allow-dry-run-without-token.
TEST_F(SecurityHttpTest, DryRunNeedsATokenOrAnExplicitFlag) {
  const std::string dry_run = R"({"file": "zz.pl", "text": "x."})";
  const auto refused = call("POST", "/api/v1/rules/dry-run", dry_run);
  EXPECT_EQ(refused.status, 403) << refused.body;
  EXPECT_EQ(body_of(refused.body).value("error", ""), "forbidden");
  EXPECT_NE(body_of(refused.body).value("detail", "").find("--allow-dry-run-without-token"), std::string::npos);

  extra_args_ = {"--allow-dry-run-without-token"};
  restart();
  const auto allowed = call("POST", "/api/v1/rules/dry-run", dry_run);
  EXPECT_EQ(allowed.status, 200) << allowed.body;
  EXPECT_EQ(body_of(allowed.body).value("redecided", -1), 0);

  extra_args_ = {"--token", "s3cret"};
  restart();
  EXPECT_EQ(call("POST", "/api/v1/rules/dry-run", dry_run).status, 401);
  const auto with_token = client_->request("POST", "/api/v1/rules/dry-run", dry_run, "application/json", "s3cret");
  EXPECT_EQ(with_token.status, 200) << with_token.body;
}

// A server reachable from the network needs a token: --bind 0.0.0.0 without --token started without a word.
TEST_F(SecurityHttpTest, NonLoopbackBindWithoutTokenIsRefusedUnlessExplicit) {
  const auto base = "timeout 30 " + std::string(WM_WMD_PATH) + " --db " + (dir_.path() / "bind.db").string() +
                    " --port 0 --rules " + WM_RULES_DIR + " --bind 0.0.0.0";
  const auto refused = run_command(base);
  EXPECT_EQ(refused.status, 2) << refused.output;
  EXPECT_NE(refused.output.find("--bind 0.0.0.0 makes the server reachable from other machines"), std::string::npos)
      << refused.output;
  EXPECT_NE(refused.output.find("--insecure-no-token"), std::string::npos);

  WmdProcess insecure({"--db", (dir_.path() / "bind.db").string(), "--port", "0", "--rules", WM_RULES_DIR, "--bind",
                       "0.0.0.0", "--insecure-no-token"});
  EXPECT_EQ(client::HttpClient(insecure.url()).request("GET", "/api/v1/health").status, 200);
  EXPECT_EQ(insecure.stop(), 0);

  WmdProcess with_token({"--db", (dir_.path() / "bind.db").string(), "--port", "0", "--rules", WM_RULES_DIR, "--bind",
                         "0.0.0.0", "--token", "s3cret"});
  EXPECT_EQ(client::HttpClient(with_token.url()).request("GET", "/api/v1/health").status, 200);
}

// No file system layout leaks: /api/v1/health showed the absolute path of the rules directory.
TEST_F(SecurityHttpTest, HealthShowsNoAbsolutePath) {
  const auto r = call("GET", "/api/v1/health");
  ASSERT_EQ(r.status, 200);
  EXPECT_EQ(r.body.find(WM_RULES_DIR), std::string::npos) << r.body;
  EXPECT_EQ(r.body.find(WM_SOURCE_DIR), std::string::npos) << r.body;
  const auto health = body_of(r.body);
  EXPECT_EQ(health["rules"]["files"][0]["path"], "prolog/world_model.pl");
  EXPECT_EQ(get_json("/api/v1/rules")["files"][0]["path"], "prolog/world_model.pl");
}

// Query answers are bounded at the edge (8 MiB): length(L, 10000000) answered 50 MB.
TEST_F(SecurityHttpTest, AHugeQueryAnswerIsRefusedNotSent) {
  const auto r = call("POST", "/api/v1/query", R"json({"goal": "length(L, 2000000)"})json");
  EXPECT_EQ(r.status, 422) << r.body.substr(0, 300);
  EXPECT_LT(r.body.size(), 4096u);
  const auto error = body_of(r.body).value("error", "");
  EXPECT_TRUE(error == "answer_too_large" || error == "query_limit") << r.body;
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
}

// A slow handler cannot hold up the I/O threads: with --threads 1, /health waited for a slow query. Handlers now
// run on their own pool and the I/O thread keeps answering.
TEST_F(SecurityHttpTest, ASlowQueryDoesNotHoldUpHealth) {
  extra_args_ = {"--threads", "1", "--rule-time-limit", "3", "--rule-inferences", "1000000000"};
  restart();
  auto slow = std::async(std::launch::async, [this] {
    const auto started = std::chrono::steady_clock::now();
    const auto r = client::HttpClient(server_->url()).request("POST", "/api/v1/query", R"({"goal": "repeat, fail"})");
    return std::make_pair(r.status, std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count());
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto started = std::chrono::steady_clock::now();
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
  const double health_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const auto [status, query_s] = slow.get();
  EXPECT_EQ(status, 422);
  EXPECT_GT(query_s, 2.0) << "the query must still have been running";
  EXPECT_LT(health_s, 0.5) << "health waited for the slow query";
}

// A full handler queue answers 503 with Retry-After at once instead of queueing without bound.
TEST_F(SecurityHttpTest, AFullHandlerQueueAnswers503WithRetryAfter) {
  extra_args_ = {"--handler-threads", "1", "--handler-queue",   "1",
                 "--rule-time-limit", "2", "--rule-inferences", "1000000000"};
  restart();
  const auto slow_query = [this] {
    return client::HttpClient(server_->url()).request("POST", "/api/v1/query", R"({"goal": "repeat, fail"})").status;
  };
  auto running = std::async(std::launch::async, slow_query);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  auto queued = std::async(std::launch::async, slow_query);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto host = "127.0.0.1:" + std::to_string(server_->port());
  const auto busy = raw_request(server_->port(), bhttp::verb::get, "/api/v1/map", {{"Host", host}});
  EXPECT_EQ(busy.result_int(), 503) << busy.body();
  EXPECT_EQ(busy[bhttp::field::retry_after], "1");
  EXPECT_EQ(body_of(busy.body()).value("error", ""), "busy");
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok") << "health runs on the I/O thread";
  EXPECT_EQ(running.get(), 422);
  EXPECT_EQ(queued.get(), 422);
  EXPECT_EQ(call("GET", "/api/v1/map").status, 200);
}

// The pid of the wmd whose database is `db` (WmdProcess does not say).
pid_t pid_of_wmd(const std::string& db) {
  for (const auto& entry : std::filesystem::directory_iterator("/proc")) {
    const auto name = entry.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::string cmdline = slurp(entry.path() / "cmdline");
    std::replace(cmdline.begin(), cmdline.end(), '\0', ' ');
    if (cmdline.find(WM_WMD_PATH) != std::string::npos && cmdline.find(db) != std::string::npos) return std::stoi(name);
  }
  return -1;
}

// utime + stime of a process [s].
double cpu_seconds(pid_t pid) {
  const auto stat = slurp("/proc/" + std::to_string(pid) + "/stat");
  std::istringstream fields(stat.substr(stat.rfind(')') + 2));  // after "pid (comm) "
  std::string field;
  double ticks = 0;
  for (int i = 3; i <= 15 && fields >> field; ++i)
    if (i == 14 || i == 15) ticks += std::stod(field);
  return ticks / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

// The accept loop survives running out of descriptors: with them exhausted, it re-armed at once and spun a core.
// Now it backs off (50 ms doubling to 1 s) and serves again once descriptors are free.
TEST_F(SecurityHttpTest, AcceptBacksOffWhenFileDescriptorsRunOut) {
  const auto db = (dir_.path() / "wm.db").string();
  const pid_t pid = pid_of_wmd(db);
  ASSERT_GT(pid, 0);
  std::size_t open_fds = 0;
  for ([[maybe_unused]] const auto& fd : std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/fd"))
    ++open_fds;
  const rlimit limit{open_fds + 8, open_fds + 8};
  ASSERT_EQ(::prlimit(pid, RLIMIT_NOFILE, &limit, nullptr), 0);

  std::vector<int> idle;
  for (int i = 0; i < 40; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<unsigned short>(server_->port()));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
    idle.push_back(fd);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const double before = cpu_seconds(pid);
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const double used = cpu_seconds(pid) - before;
  EXPECT_LT(used, 0.2) << "wmd used " << used << " s of CPU in 1 s with its descriptors exhausted";

  for (const int fd : idle) ::close(fd);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  int status = 0;
  while (status != 200 && std::chrono::steady_clock::now() < deadline) {
    try {
      status = client::HttpClient(server_->url(), std::chrono::seconds(3)).request("GET", "/api/v1/health").status;
    } catch (const client::ConnectionError&) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  EXPECT_EQ(status, 200) << "wmd must serve again once the idle clients are gone";
}

}  // namespace
}  // namespace wm::testing
