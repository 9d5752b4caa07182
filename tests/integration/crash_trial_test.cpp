// Crash trials: kill -9 wmd while several clients post scans and primitives over loopback HTTP, restart it on
// the same database, and check what the kill left: nothing acknowledged lost, nothing applied twice (retries
// with their request id are answered, not applied), nothing half applied (every journaled scan with exactly
// the line decisions its body yields), the grid revision never going back, and PRAGMA integrity_check.
//
// WM_CRASH_TRIALS=N sets the number of trials (default 20, what CI runs); scripts/crash_trials.sh N runs more.
// WM_CRASH_SEED=S replays a run (the seed is printed).
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "e2e_fixture.h"
#include "logs/carmen_log_reader.h"

namespace wm::testing {
namespace {

namespace http = boost::beast::http;

struct Reply {
  int status = 0;
  std::string body;
  bool replayed = false;  // Idempotent-Replayed: true
};

// One request on a fresh loopback connection. nullopt when no whole answer came back (refused, reset, timed
// out): the request may or may not have been applied.
std::optional<Reply> send(int port, http::verb verb, const std::string& target, const std::string& body,
                          const std::string& request_id, std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
  Headers headers{{"Host", "127.0.0.1"}};
  if (!request_id.empty()) headers.emplace_back("Idempotency-Key", request_id);
  try {
    const auto res = raw_request(port, verb, target, headers, body, timeout);
    return Reply{static_cast<int>(res.result_int()), res.body(), res["Idempotent-Replayed"] == "true"};
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::optional<Reply> post(int port, const std::string& target, const std::string& body, const std::string& request_id) {
  return send(port, http::verb::post, target, body, request_id);
}

// Read access to the database file while wmd is down (or beside it: WAL readers do not block the writer).
class Db {
 public:
  explicit Db(const std::filesystem::path& path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK)
      throw std::runtime_error("cannot open " + path.string());
    sqlite3_busy_timeout(db_, 5000);
  }
  ~Db() { sqlite3_close(db_); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

  // Every row as text (NULL as "NULL").
  std::vector<std::vector<std::string>> rows(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK)
      throw std::runtime_error(std::string("sql: ") + sqlite3_errmsg(db_) + " in " + sql);
    std::vector<std::vector<std::string>> result;
    int rc = 0;
    while ((rc = sqlite3_step(stmt)) == SQLITE_ROW) {
      std::vector<std::string> row;
      for (int i = 0; i < sqlite3_column_count(stmt); ++i) {
        const auto* text = sqlite3_column_text(stmt, i);
        row.emplace_back(text ? reinterpret_cast<const char*>(text) : "NULL");
      }
      result.push_back(std::move(row));
    }
    sqlite3_finalize(stmt);
    if (rc != SQLITE_DONE) throw std::runtime_error(std::string("sql: ") + sqlite3_errmsg(db_) + " in " + sql);
    return result;
  }
  std::int64_t number(const std::string& sql) { return std::stoll(rows(sql).at(0).at(0)); }

 private:
  sqlite3* db_ = nullptr;
};

json scan_body(const fusion::LaserScan& scan, double stamp) {
  json ranges = json::array();
  for (const double r : scan.ranges_m) ranges.push_back(std::isfinite(r) ? json(r) : json(nullptr));
  const double sxy = 0.03, sth = 0.5 * M_PI / 180;  // as wmctl replay: corrected poses, good but not exact
  return {{"sensor", "laser"},
          {"source", "crash-robot"},
          {"stamp", stamp},
          {"pose", {{"x", scan.sensor_pose.x_m}, {"y", scan.sensor_pose.y_m}, {"theta", scan.sensor_pose.theta_rad}}},
          {"angle_min", scan.angle_min_rad},
          {"angle_increment", scan.angle_increment_rad},
          {"ranges", ranges},
          {"range_min", scan.range_min_m},
          {"range_max", scan.range_max_m},
          {"sigma_range", scan.sigma_range_m},
          {"pose_cov", {{sxy * sxy, 0, 0}, {0, sxy * sxy, 0}, {0, 0, sth * sth}}}};
}

// Two segments between returns of the scan, in the world frame: primitives made of the same real data.
std::optional<json> primitives_body(const fusion::LaserScan& scan, double stamp) {
  std::vector<Eigen::Vector2d> hits;
  for (std::size_t i = 0; i < scan.ranges_m.size(); i += scan.ranges_m.size() / 6) {
    const double r = scan.ranges_m[i];
    if (!std::isfinite(r) || r < scan.range_min_m || r >= scan.range_max_m) continue;
    const double a = scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
    hits.push_back(scan.sensor_pose.transform_point({r * std::cos(a), r * std::sin(a)}));
  }
  if (hits.size() < 4) return std::nullopt;
  json segments = json::array();
  for (std::size_t k = 0; k < 2; ++k)
    segments.push_back(
        {{"p0", {hits[2 * k].x(), hits[2 * k].y()}}, {"p1", {hits[2 * k + 1].x(), hits[2 * k + 1].y()}}});
  return json{{"source", "crash-robot"}, {"stamp", stamp}, {"sensor", "laser"}, {"segments", segments}};
}

enum class Kind { scan, primitives };

struct Sent {
  Kind kind;
  std::size_t body;                  // index into the pool of its kind
  std::optional<json> acknowledged;  // the 200 answer, once one came
};

class CrashTrialTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::filesystem::path data = std::filesystem::path(WM_SOURCE_DIR) / "tests/data/carmen";
    for (const auto* name : {"intel-corrected-excerpt.log.gz", "freiburg-079-corrected-excerpt.log"}) {
      logs::CarmenLogReader reader(data / name);
      while (auto s = reader.next()) {
        scans_.push_back(scan_body(s->scan, s->timestamp_s).dump());
        if (auto p = primitives_body(s->scan, s->timestamp_s)) primitives_.push_back(p->dump());
      }
    }
    ASSERT_GE(scans_.size(), 40u);
    ASSERT_GE(primitives_.size(), 20u);
  }

  std::filesystem::path db() const { return dir_.path() / "wm.db"; }
  void start() {
    server_ = std::make_unique<WmdProcess>(
        std::vector<std::string>{"--db", db().string(), "--port", "0", "--rules", WM_RULES_DIR});
  }
  int port() const { return server_->port(); }
  const std::string& pool(Kind kind, std::size_t i) const { return kind == Kind::scan ? scans_[i] : primitives_[i]; }
  static const char* target(Kind kind) { return kind == Kind::scan ? "/api/v1/scans" : "/api/v1/primitives"; }

  std::int64_t grid_revision() {
    const auto r = send(port(), http::verb::get, "/api/v1/grid?bbox=0,0,0.1,0.1", "", "");
    EXPECT_TRUE(r && r->status == 200) << (r ? r->body : "no answer");
    return r && r->status == 200 ? json::parse(r->body).at("revision").get<std::int64_t>() : -1;
  }

  TempDir dir_;
  std::vector<std::string> scans_, primitives_;
  std::unique_ptr<WmdProcess> server_;
};

TEST_F(CrashTrialTest, ARetryWithTheSameRequestIdIsAnsweredNotApplied) {
  start();
  const auto first = post(port(), "/api/v1/primitives", primitives_[0], "prims-1");
  ASSERT_TRUE(first && first->status == 200) << (first ? first->body : "no answer");
  EXPECT_FALSE(first->replayed);
  const auto again = post(port(), "/api/v1/primitives", primitives_[0], "prims-1");
  ASSERT_TRUE(again && again->status == 200) << (again ? again->body : "no answer");
  EXPECT_TRUE(again->replayed);
  EXPECT_EQ(json::parse(again->body), json::parse(first->body));
  const auto scan = post(port(), "/api/v1/scans", scans_[0], "scan-1");
  ASSERT_TRUE(scan && scan->status == 200) << (scan ? scan->body : "no answer");
  ASSERT_FALSE(json::parse(scan->body)["lines"].is_null()) << "the first Intel scan has walls";
  server_->crash();
  start();
  const auto scan_again = post(port(), "/api/v1/scans", scans_[0], "\"scan-1\"");  // the quoted form is the same id
  ASSERT_TRUE(scan_again && scan_again->status == 200);
  EXPECT_TRUE(scan_again->replayed);
  EXPECT_EQ(json::parse(scan_again->body), json::parse(scan->body));
  EXPECT_EQ(grid_revision(), 1);
  // Without an id every post is applied.
  const auto plain = post(port(), "/api/v1/primitives", primitives_[0], "");
  ASSERT_TRUE(plain && plain->status == 200);
  EXPECT_EQ(json::parse(plain->body)["seq"], json::parse(first->body)["seq"].get<int>() + 2);
}

TEST_F(CrashTrialTest, ARequestIdReusedForAnotherRequestIsRefused) {
  start();
  ASSERT_EQ(post(port(), "/api/v1/primitives", primitives_[0], "id-a")->status, 200);
  const auto other_body = post(port(), "/api/v1/primitives", primitives_[1], "id-a");
  ASSERT_TRUE(other_body);
  EXPECT_EQ(other_body->status, 409) << other_body->body;
  EXPECT_EQ(json::parse(other_body->body)["error"], "request_id_conflict");
  EXPECT_EQ(post(port(), "/api/v1/scans", scans_[0], "id-a")->status, 409);
  for (const std::string& bad : {std::string(201, 'x'), std::string("a b"), std::string("caf\xc3\xa9")}) {
    const auto r = post(port(), "/api/v1/primitives", primitives_[0], bad);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400) << r->body;
  }
  // A refused request stores nothing: its id is still free.
  const auto ok = post(port(), "/api/v1/scans", scans_[0], "id-b");
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
}

TEST_F(CrashTrialTest, TheGridRevisionNeverGoesBackAcrossRestarts) {
  start();
  for (std::size_t i = 0; i < 3; ++i) ASSERT_EQ(post(port(), "/api/v1/scans", scans_[i], "")->status, 200);
  EXPECT_EQ(grid_revision(), 3);
  ASSERT_EQ(server_->stop(), 0);  // a clean stop flushes the tiles: nothing is replayed at start
  start();
  EXPECT_EQ(grid_revision(), 3);
  const auto fourth = post(port(), "/api/v1/scans", scans_[3], "");
  ASSERT_TRUE(fourth);
  EXPECT_EQ(json::parse(fourth->body)["grid_revision"], 4);
  server_->crash();
  start();
  EXPECT_EQ(grid_revision(), 4);
}

TEST_F(CrashTrialTest, KillNineDuringConcurrentIngestLosesNothingAndAppliesNothingTwiceOrByHalf) {
  const int trials = std::getenv("WM_CRASH_TRIALS") ? std::atoi(std::getenv("WM_CRASH_TRIALS")) : 20;
  const auto seed = std::getenv("WM_CRASH_SEED")
                        ? static_cast<unsigned>(std::strtoul(std::getenv("WM_CRASH_SEED"), nullptr, 10))
                        : std::random_device{}();
  std::cout << "crash trials: " << trials << ", WM_CRASH_SEED=" << seed << "\n";
  std::mt19937 rng(seed);

  std::map<std::string, Sent> sent;  // every request ever sent, by request id
  // What each scan body yields: whether it has lines and how many segment decisions (the extractor is
  // deterministic in the body). Learnt by posting every body once before the trials.
  std::vector<std::int64_t> scan_segments(scans_.size(), -1);
  auto segments_of = [](const json& decisions) {
    return std::count_if(decisions.begin(), decisions.end(), [](const json& d) {
      return d["index"].get<int>() >= 0 &&
             d["explanation"].get<std::string>().find("through sparse grazing returns") == std::string::npos;
    });
  };
  std::int64_t max_revision = 0;
  start();
  for (std::size_t i = 0; i < scans_.size(); ++i) {
    const std::string id = "warm-s" + std::to_string(i);
    const auto r = post(port(), "/api/v1/scans", scans_[i], id);
    ASSERT_TRUE(r && r->status == 200) << (r ? r->body : "no answer");
    const auto answer = json::parse(r->body);
    scan_segments[i] = answer["lines"].is_null() ? 0 : segments_of(answer["lines"]["decisions"]);
    sent[id] = {Kind::scan, i, answer};
    max_revision = answer["grid_revision"];
  }

  std::size_t unknown_total = 0, committed_unknown = 0, acknowledged_total = 0, retried = 0;
  const auto started = std::chrono::steady_clock::now();
  for (int trial = 0; trial < trials; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial) + " (WM_CRASH_SEED=" + std::to_string(seed) + ")");
    // Load: two scan clients and two primitive clients, each posting until the kill.
    std::mutex mutex;
    std::atomic<bool> killed{false};
    std::vector<std::thread> clients;
    std::vector<std::string> this_trial;
    for (int c = 0; c < 4; ++c) {
      const Kind kind = c < 2 ? Kind::scan : Kind::primitives;
      const std::size_t offset = rng();
      clients.emplace_back([&, c, kind, offset, trial] {
        for (std::size_t n = 0;; ++n) {
          const std::size_t body = (offset + n) % (kind == Kind::scan ? scans_.size() : primitives_.size());
          const std::string id = "t" + std::to_string(trial) + "c" + std::to_string(c) + "n" + std::to_string(n);
          {
            std::lock_guard lock(mutex);
            sent[id] = {kind, body, std::nullopt};
            this_trial.push_back(id);
          }
          const auto r = post(port(), target(kind), pool(kind, body), id);
          if (!r) return;  // killed: the outcome of this one is unknown
          std::lock_guard lock(mutex);
          if (r->status == 200) {
            sent[id].acknowledged = json::parse(r->body);
          } else if (r->status != 503) {  // 503: busy, nothing applied (a retry below applies it)
            ADD_FAILURE() << "status " << r->status << ": " << r->body;
            return;
          }
          if (killed) return;
        }
      });
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(std::uniform_int_distribution<int>(150, 900)(rng)));
    killed = true;
    server_->crash();
    for (auto& t : clients) t.join();

    // The file as the kill left it.
    std::map<std::string, std::vector<std::string>> stored;  // request_id -> kind, seq, grid_revision, lines_seq
    {
      Db file(db());
      ASSERT_EQ(file.rows("PRAGMA integrity_check").at(0).at(0), "ok");
      for (auto& row : file.rows("SELECT request_id, kind, seq, grid_revision, lines_seq FROM requests"))
        stored[row[0]] = {row[1], row[2], row[3], row[4]};
      // Every scan and every client observation came from one of our requests, once.
      ASSERT_EQ(file.number("SELECT COUNT(*) FROM scans"),
                file.number("SELECT COUNT(*) FROM requests WHERE kind = 'scan'"));
      ASSERT_EQ(file.number("SELECT COUNT(*) FROM observations WHERE kind = 'client'"),
                file.number("SELECT COUNT(*) FROM requests WHERE kind = 'primitives'"));
      ASSERT_EQ(file.number("SELECT COUNT(*) FROM observations WHERE kind = 'scan'"),
                file.number("SELECT COUNT(*) FROM scans WHERE lines_seq IS NOT NULL"));
      ASSERT_EQ(file.number("SELECT COALESCE(MAX(seq), 0) FROM scans"), file.number("SELECT COUNT(*) FROM scans"));
      // Nothing half applied: each stored request has its journal entry and exactly the decisions its body
      // yields (a scan: its line observation iff its body has lines).
      std::map<std::string, std::int64_t> scan_lines, decisions_of;
      for (auto& row : file.rows("SELECT seq, COALESCE(lines_seq, 'NULL') FROM scans"))
        scan_lines[row[0]] = row[1] == "NULL" ? 0 : std::stoll(row[1]);
      // (A scan's line observation also holds views continuing elements past their ends through sparse returns,
      // as many as the map had such elements then: they are counted apart, and their indices follow the lines'.)
      for (auto& row :
           file.rows("SELECT observation_seq, COUNT(*) FROM decisions WHERE idx >= 0 AND explanation NOT "
                     "LIKE '%a continuation of e% through sparse grazing returns%' GROUP BY observation_seq"))
        decisions_of[row[0]] = std::stoll(row[1]);
      for (auto& row : file.rows("SELECT observation_seq, COUNT(*), MAX(idx) FROM decisions WHERE idx >= 0 AND "
                                 "observation_seq IN (SELECT lines_seq FROM scans) GROUP BY observation_seq"))
        ASSERT_EQ(std::stoll(row[2]) + 1, std::stoll(row[1])) << "observation " << row[0] << ": decisions missing";
      for (const auto& [id, row] : stored) {
        const auto it = sent.find(id);
        ASSERT_NE(it, sent.end()) << "unknown request id " << id;
        if (row[0] == "scan") {
          ASSERT_EQ(it->second.kind, Kind::scan);
          ASSERT_TRUE(scan_lines.count(row[1])) << id << ": the scan is not journaled";
          const auto expected = scan_segments[it->second.body];
          ASSERT_EQ(row[3] == "NULL" ? 0 : 1, expected > 0 ? 1 : 0) << id;
          if (expected > 0) {
            ASSERT_EQ(std::to_string(scan_lines[row[1]]), row[3]) << id;
            ASSERT_EQ(decisions_of[row[3]], expected) << id << ": the scan's line decisions are not all there";
          }
        } else {
          ASSERT_EQ(it->second.kind, Kind::primitives);
          ASSERT_EQ(decisions_of[row[1]], 2) << id << ": the primitives' decisions are not all there";
        }
      }
      max_revision = std::max(max_revision, file.number("SELECT COALESCE(MAX(seq), 0) FROM scans"));
    }
    // Nothing acknowledged lost: every 200 so far is in the file with the sequence it answered.
    for (const auto& [id, s] : sent) {
      if (!s.acknowledged) continue;
      const auto it = stored.find(id);
      ASSERT_NE(it, stored.end()) << id << " was acknowledged and is gone";
      ASSERT_EQ(it->second[1], std::to_string((*s.acknowledged)["seq"].get<std::int64_t>())) << id;
    }

    start();
    // The revision is the journal's scan count: never behind anything answered before the kill.
    const auto revision = grid_revision();
    ASSERT_EQ(revision, max_revision);
    // Retries: an acknowledged request is answered as it was; one whose answer the kill cut off is answered
    // from the file if it committed, applied now if it did not, and never twice.
    for (const auto& id : this_trial) {
      auto& s = sent[id];
      const auto r = post(port(), target(s.kind), pool(s.kind, s.body), id);
      ASSERT_TRUE(r && r->status == 200) << id << ": " << (r ? r->body : "no answer");
      ++retried;
      const auto answer = json::parse(r->body);
      if (s.acknowledged) {
        ++acknowledged_total;
        ASSERT_TRUE(r->replayed) << id;
        ASSERT_EQ(answer, *s.acknowledged) << id;
      } else {
        ++unknown_total;
        ASSERT_EQ(r->replayed, stored.count(id) == 1) << id;
        if (r->replayed) {
          ++committed_unknown;
          ASSERT_EQ(std::to_string(answer["seq"].get<std::int64_t>()), stored[id][1]) << id;
        }
        s.acknowledged = answer;
      }
      if (s.kind == Kind::scan) {
        ASSERT_EQ(answer["lines"].is_null() ? 0 : segments_of(answer["lines"]["decisions"]), scan_segments[s.body])
            << id;
        max_revision = std::max(max_revision, answer["grid_revision"].get<std::int64_t>());
      }
    }
    ASSERT_EQ(grid_revision(), max_revision);
  }
  server_->stop();
  const auto seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  std::cout << "crash trials: " << trials << " kills in " << seconds << " s; " << acknowledged_total
            << " acknowledged requests retried and answered the same, " << unknown_total << " cut off by the kill ("
            << committed_unknown << " had committed, the rest applied on retry), " << retried
            << " retries, grid revision " << max_revision << "\n";
}

}  // namespace
}  // namespace wm::testing

namespace wm::testing {
namespace {

// The decisions of a run, each as what it did (action, rule, element, object, before/after), without the clock.
std::vector<json> decision_log(int port) {
  const auto r = send(port, http::verb::get, "/api/v1/decisions?limit=10000", "", "");
  if (!r || r->status != 200) {
    ADD_FAILURE() << "GET /api/v1/decisions: " << (r ? r->body : "no answer");
    return {};
  }
  std::vector<json> log;
  const auto body = json::parse(r->body);  // kept: a range-for over a temporary's member would dangle
  for (auto d : body["decisions"]) {
    json kept;
    for (const auto* key : {"seq", "observation", "action", "rule", "element", "object", "before", "after"})
      if (d.contains(key)) kept[key] = d[key];
    log.push_back(std::move(kept));
  }
  return log;
}

// One client posts scans one at a time, as a robot would; wmd is killed (kill -9) at random moments and restarted
// on the same file, and the client retries what was not answered with its request id. The decision log at the end
// must equal a clean run's, grid trims included: what decides (the grid, the region a trim looks at, a trim that a
// crash left undone) is rebuilt from the committed state at start.
TEST_F(CrashTrialTest, KilledAndRestartedRunsDecideAsACleanRunDoes) {
  const std::size_t kScans = scans_.size();  // the two excerpts: 47 scans, 4 grid trims
  ASSERT_GE(kScans, 40u);
  const auto run = [&](std::mt19937* kills) {
    start();
    int restarts = 0;
    for (std::size_t i = 0; i < kScans; ++i) {
      const std::string id = "det-s" + std::to_string(i);
      std::thread killer;
      std::atomic<bool> done{false};
      std::atomic<bool> fired{false};
      if (kills && std::uniform_int_distribution<int>(0, 5)(*kills) == 0) {
        const int delay_us = std::uniform_int_distribution<int>(0, 6000)(*kills);
        killer = std::thread([&, delay_us] {
          std::this_thread::sleep_for(std::chrono::microseconds(delay_us));
          if (!done) {
            fired = true;
            server_->crash();
          }
        });
      }
      auto r = post(port(), "/api/v1/scans", scans_[i], id);
      done = true;
      if (killer.joinable()) killer.join();
      // The killer may have read `done` just before the answer came and killed wmd after it: start it again, or
      // the next request (the decisions read after the last scan) finds no server.
      if (fired && r && r->status == 200) {
        start();
        ++restarts;
      }
      while (!r || r->status != 200) {
        EXPECT_TRUE(!r || r->status == 503) << r->status << ": " << r->body;
        server_->crash();  // whether or not the killer got there first
        start();
        ++restarts;
        r = post(port(), "/api/v1/scans", scans_[i], id);
      }
    }
    auto log = decision_log(port());
    server_->stop();
    return std::pair{log, restarts};
  };
  const auto [clean, none] = run(nullptr);
  ASSERT_FALSE(clean.empty());
  const std::size_t trims =
      std::count_if(clean.begin(), clean.end(), [](const json& d) { return d["rule"] == "grid_trimmed"; });
  const unsigned seed = std::random_device{}();
  std::mt19937 kills(seed);
  SCOPED_TRACE("WM_CRASH_SEED=" + std::to_string(seed));
  int total_restarts = 0, trials = 0;
  for (; trials < 4; ++trials) {
    std::filesystem::remove(db());
    std::filesystem::remove(db().string() + "-wal");
    std::filesystem::remove(db().string() + "-shm");
    const auto [log, restarts] = run(&kills);
    total_restarts += restarts;
    ASSERT_EQ(log.size(), clean.size()) << "trial " << trials << " after " << restarts << " restarts";
    for (std::size_t k = 0; k < log.size(); ++k)
      ASSERT_EQ(log[k], clean[k]) << "trial " << trials << ", decision " << k << " after " << restarts << " restarts";
  }
  std::cout << "determinism: " << trials << " trials, " << total_restarts << " kills, " << clean.size()
            << " decisions each (" << trims << " grid trims), all equal to the clean run\n";
  EXPECT_GT(total_restarts, 0);
}

}  // namespace
}  // namespace wm::testing
