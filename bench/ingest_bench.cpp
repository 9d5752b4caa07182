// End-to-end ingest: the 910 laser scans of the Intel Research Lab CARMEN log posted to a real wmd child process
// over loopback HTTP/1.1, by R = 1, 4, 16 robots at once (one thread and one keep-alive connection each,
// robot k posting scans k, k + R, ... in order as observer "robot-k"), with --sync full on a fresh database.
// Baselines in the same run:
//  - the same ingest against wmd started with the extra arguments in WM_BENCH_BASELINE_ARGS (space-separated;
//    unset: --handler-threads 8, today's default), or against another wmd build, WM_BENCH_BASELINE_WMD=PATH (then
//    with no extra arguments unless given): a refactor's wmd against the one before it;
//  - raw SQLite (WAL, synchronous=FULL) inserting one Intel scan body per transaction, the fsync ceiling of a
//    writer that commits every scan on its own, and 16 per transaction, what group commit could reach.
// PostgreSQL: BM_IngestPostgres is the same ingest with wmd's store in a private PostgreSQL 15 server on this
// machine (tests/support/postgres.sh; fsync on, synchronous_commit on), against BM_Ingest (SQLite) of the same run,
// with PostgreSQL's own commit rate beside it (BM_PostgresCommit_1RowPerTxn: one scan body per transaction, libpq).
// Maps: BM_IngestMaps feeds 1 or 4 maps of one wmd at once (4 robots each), and BM_IngestMapsBesideAHeldMap one
// map while another map's writer is stuck on a write lock held from outside, against one map alone.
// Beams: BM_IngestBeams_<set> posts scans of more beams with 1 and 16 robots: CSAIL's 361-beam log, and a 1 081-beam
// 270° scanner (0.25° apart, 20 m, σ 1 cm) ray-cast on a 40 Hz drive through two plans of different kinds, GDC1 and
// the Open-RMF office (bench/support/dense_drive.h: the route is found in the plan, not drawn for it), against the
// Intel log's 180 beams with 16 robots (scans/s; beams/s, p50/p99 answer times and wmd's CPU per beam as counters,
// the CPU by thread and by network function on stderr). BM_IngestPaced40HzAmongFlooders_<plan>: one robot posts on
// a 40 Hz schedule while 15 post as fast as they can; its answer times and the pace it kept.
// WM_BENCH_QUICK caps the log at 200 scans and the dense drives at 160 scans, one plan, 16 robots, 20 paced scans;
// WM_BENCH_LOG=FILE posts another CARMEN log's laser scans (the first 2000) in the Intel log's place.
#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <libpq-fe.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "apriori/import/rmf_import.h"
#include "bench/support/dense_drive.h"
#include "bench/support/ratio_reporter.h"
#include "bench/support/wmd_child.h"
#include "logs/carmen_log_reader.h"
#include "logs/scan_body.h"
#include "tools/raycast/raycast.h"

namespace {

using wm::bench::Connection;
using wm::bench::TempDir;
using wm::bench::WmdProcess;
namespace beast = boost::beast;
namespace http = boost::beast::http;
namespace net = boost::asio;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kRobotCounts[] = {1, 4, 16};
constexpr auto kRetryPause = std::chrono::milliseconds(5);  // instead of Retry-After's whole second: we measure load

// WM_BENCH_LOG names another CARMEN log (e.g. aces-corrected.log.gz), else the shared copy of the Intel log, else the
// whole copy the tests ship.
fs::path intel_log() {
  if (const char* chosen = std::getenv("WM_BENCH_LOG"); chosen && *chosen) return chosen;
  const fs::path shared = fs::path(WM_SHARED_DATA_DIR) / "carmen";
  if (fs::exists(shared / "intel-corrected.log.gz")) return shared / "intel-corrected.log.gz";
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(shared, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("intel", 0) == 0 && name.size() > 7 && name.compare(name.size() - 7, 7, ".log.gz") == 0)
      return entry.path();
  }
  return fs::path(WM_TESTS_CARMEN_DIR) / "intel-corrected.log.gz";
}

std::vector<wm::logs::LogScan> read_scans(const fs::path& log, std::size_t limit) {
  wm::logs::CarmenLogReader reader(log);
  std::vector<wm::logs::LogScan> scans;
  for (auto scan = reader.next(); scan && scans.size() < limit; scan = reader.next()) scans.push_back(std::move(*scan));
  return scans;
}

// The body wmctl replay posts (its default pose uncertainty included, so the server does the same work).
std::string scan_body(const wm::logs::LogScan& s, const std::string& observer) {
  auto body = wm::logs::laser_scan_body(s.scan, observer, s.timestamp_s);
  constexpr double kSigmaXy = 0.03, kSigmaTheta = 0.0087;
  body["pose_cov"] = {{kSigmaXy * kSigmaXy, 0, 0}, {0, kSigmaXy * kSigmaXy, 0}, {0, 0, kSigmaTheta * kSigmaTheta}};
  return body.dump();
}

// Every robot's bodies, in its posting order: robot k gets scans k, k + R, ...
std::vector<std::vector<std::string>> robot_bodies(const std::vector<wm::logs::LogScan>& scans, int robots) {
  std::vector<std::vector<std::string>> bodies(static_cast<std::size_t>(robots));
  for (std::size_t i = 0; i < scans.size(); ++i)
    bodies[i % bodies.size()].push_back(scan_body(scans[i], "robot-" + std::to_string(i % bodies.size())));
  return bodies;
}

// The q-quantile of sorted values (nearest rank), 0 for none.
double quantile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0.0;
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(sorted.size())));
  return sorted[std::max<std::size_t>(rank, 1) - 1];
}

std::size_t beams_of(const std::vector<wm::logs::LogScan>& scans) {
  std::size_t beams = 0;
  for (const auto& s : scans) beams += s.scan.ranges_m.size();
  return beams;
}

std::vector<std::string> split_words(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

// What one robot saw.
struct RobotTally {
  std::size_t accepted = 0;
  std::size_t retries = 0;
  std::vector<double> latencies_ms;  // per HTTP exchange, a 503 included
};

// Posts `bodies` in order on `connection`, retrying the same body after a 503; stops at the first other status,
// at a connection error, or when another robot failed.
void run_robot(Connection& connection, const std::vector<std::string>& bodies, RobotTally& tally,
               std::atomic<bool>& failed, std::string& error, std::mutex& error_mutex, const std::string& target) {
  const auto fail = [&](const std::string& what) {
    const std::lock_guard lock(error_mutex);
    if (error.empty()) error = what;
    failed = true;
  };
  try {
    for (const auto& body : bodies) {
      for (;;) {
        if (failed) return;
        const auto start = Clock::now();
        const auto answer = connection.request(http::verb::post, target, body);
        tally.latencies_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
        if (answer.status >= 200 && answer.status < 300) {
          ++tally.accepted;
          break;
        }
        if (answer.status != 503)
          return fail("POST " + target + ": " + std::to_string(answer.status) + " " + answer.body.substr(0, 300));
        ++tally.retries;
        std::this_thread::sleep_for(kRetryPause);
      }
    }
  } catch (const std::exception& e) {
    fail(std::string("connection: ") + e.what());
  }
}

// Where the time went: the processing network's own counters (GET /api/v1/network), per executor and function.
void print_network_profile(const std::string& label, int robots, const std::string& body, double beams) {
  const auto network = nlohmann::json::parse(body, nullptr, false);
  if (network.is_discarded() || !network.contains("executors")) return;
  std::fprintf(stderr, "network profile, %s, %d robots (%s):\n", label.c_str(), robots,
               network["source"].get<std::string>().c_str());
  for (const auto& e : network["executors"])
    std::fprintf(stderr, "  executor %-10s load %.2f (busy %.2f s)\n", e["name"].get<std::string>().c_str(),
                 e["load"].get<double>(), e["busy_s"].get<double>());
  for (const auto& f : network["functions"])
    if (f["activations"].get<std::uint64_t>() > 0)
      std::fprintf(stderr, "  %-12s %-16s %7llu activations, mean %.3f ms, busy %.2f s, %.0f ns per beam\n",
                   f["component"].get<std::string>().c_str(), f["function"].get<std::string>().c_str(),
                   static_cast<unsigned long long>(f["activations"].get<std::uint64_t>()), f["mean_ms"].get<double>(),
                   f["busy_s"].get<double>(), beams > 0 ? 1e9 * f["busy_s"].get<double>() / beams : 0.0);
}

// wmd's CPU per scan and per beam, all threads and by thread (the executors name theirs: grids, world, storage,
// lines; HTTP and JSON run on threads named wmd).
void print_cpu_by_thread(const std::string& label, int robots, const WmdProcess& wmd,
                         const std::map<std::string, double>& threads_before, double wmd_cpu_s, std::size_t accepted,
                         double beams) {
  std::fprintf(stderr,
               "wmd CPU per scan, %s, %d robots: %.3f ms (%.0f ns per beam); by thread, ms per scan (ns per beam):",
               label.c_str(), robots, 1000.0 * wmd_cpu_s / static_cast<double>(accepted), 1e9 * wmd_cpu_s / beams);
  for (const auto& [name, seconds] : wmd.cpu_seconds_by_thread()) {
    const auto before = threads_before.find(name);
    const double spent = seconds - (before == threads_before.end() ? 0.0 : before->second);
    std::fprintf(stderr, " %s %.3f (%.0f)", name.c_str(), 1000.0 * spent / static_cast<double>(accepted),
                 1e9 * spent / beams);
  }
  std::fprintf(stderr, "\n");
}

void ingest(benchmark::State& state, const std::vector<wm::logs::LogScan>* scans,
            const std::vector<std::string>* wmd_args, const std::string* binary, const std::string* label) {
  const int robots = static_cast<int>(state.range(0));
  const auto bodies = robot_bodies(*scans, robots);
  const double beams_per_scan = static_cast<double>(beams_of(*scans)) / static_cast<double>(scans->size());
  std::size_t accepted = 0, retries = 0;
  std::vector<double> latencies_ms;
  double wmd_cpu_s = 0, beams = 0;
  try {
    WmdProcess wmd(*wmd_args, *binary);
    // Connections opened before the clock starts: we time ingest, not the handshakes.
    std::vector<std::unique_ptr<Connection>> connections;
    for (int k = 0; k < robots; ++k) connections.push_back(std::make_unique<Connection>(wmd.port()));
    std::string error;
    const double cpu_before = wmd.cpu_seconds();
    const auto threads_before = wmd.cpu_seconds_by_thread();
    for (auto _ : state) {
      std::vector<RobotTally> tallies(static_cast<std::size_t>(robots));
      std::atomic<bool> failed{false};
      std::mutex error_mutex;
      std::vector<std::thread> threads;
      for (std::size_t k = 0; k < tallies.size(); ++k)
        threads.emplace_back(run_robot, std::ref(*connections[k]), std::cref(bodies[k]), std::ref(tallies[k]),
                             std::ref(failed), std::ref(error), std::ref(error_mutex), std::string("/api/v1/scans"));
      for (auto& t : threads) t.join();
      for (const auto& t : tallies) {
        accepted += t.accepted;
        retries += t.retries;
        latencies_ms.insert(latencies_ms.end(), t.latencies_ms.begin(), t.latencies_ms.end());
      }
      if (failed) break;
    }
    wmd_cpu_s = wmd.cpu_seconds() - cpu_before;
    beams = static_cast<double>(accepted) * beams_per_scan;
    if (accepted > 0) print_cpu_by_thread(*label, robots, wmd, threads_before, wmd_cpu_s, accepted, beams);
    try {
      Connection c(wmd.port());
      const auto answer = c.request(http::verb::get, "/api/v1/network");
      if (answer.status == 200) print_network_profile(*label, robots, answer.body, beams);
    } catch (const std::exception&) {
      // a profile is a bonus; the figures above stand without it
    }
    connections.clear();
    if (!error.empty()) return state.SkipWithError(error.c_str());
    if (!wmd.stop()) return state.SkipWithError("wmd did not exit 0 on SIGTERM");
  } catch (const std::exception& e) {
    return state.SkipWithError(e.what());
  }
  std::sort(latencies_ms.begin(), latencies_ms.end());
  double sum = 0;
  for (double l : latencies_ms) sum += l;
  state.SetItemsProcessed(static_cast<std::int64_t>(accepted));
  state.SetLabel(*label);
  state.counters["robots"] = robots;
  state.counters["scans"] = static_cast<double>(accepted);
  state.counters["beams_per_s"] = benchmark::Counter(beams, benchmark::Counter::kIsRate);
  state.counters["retries"] = static_cast<double>(retries);
  state.counters["mean_ms"] = latencies_ms.empty() ? 0.0 : sum / static_cast<double>(latencies_ms.size());
  state.counters["p50_ms"] = quantile(latencies_ms, 0.50);
  state.counters["p99_ms"] = quantile(latencies_ms, 0.99);
  // wmd's CPU per accepted scan and per beam, all threads: scans/s can reach at most cores / this, whatever else runs.
  state.counters["cpu_ms_per_scan"] = accepted == 0 ? 0.0 : 1000.0 * wmd_cpu_s / static_cast<double>(accepted);
  state.counters["cpu_ns_per_beam"] = beams == 0 ? 0.0 : 1e9 * wmd_cpu_s / beams;
}

// One robot at a fixed pace among flooders: robot 0 posts its scans on a 40 Hz schedule (sleep until its slot; a
// late answer sends the next scan at once, none is skipped) while the other 15 post theirs as fast as they can,
// going round them again until the paced robot is done. Its answer times (from its post to its 2xx, 503 retries
// included) and whether it kept the pace are the figures; the flooders' scans/s beside them.
constexpr int kFlooders = 15;
constexpr auto kPacedPeriod = std::chrono::microseconds(25'000);  // 40 Hz

void ingest_paced(benchmark::State& state, const std::vector<wm::logs::LogScan>* scans, std::size_t paced_scans,
                  const std::string* label) {
  const int robots = kFlooders + 1;
  const auto bodies = robot_bodies(*scans, robots);
  const double beams_per_scan = static_cast<double>(beams_of(*scans)) / static_cast<double>(scans->size());
  std::vector<double> paced_ms;
  std::size_t flooded = 0, late = 0;
  double wmd_cpu_s = 0, paced_span_s = 0, beams = 0;
  try {
    WmdProcess wmd({});
    std::vector<std::unique_ptr<Connection>> connections;
    for (int k = 0; k < robots; ++k) connections.push_back(std::make_unique<Connection>(wmd.port()));
    std::string error;
    std::mutex error_mutex;
    const auto fail = [&](const std::string& what) {
      const std::lock_guard lock(error_mutex);
      if (error.empty()) error = what;
    };
    const double cpu_before = wmd.cpu_seconds();
    const auto threads_before = wmd.cpu_seconds_by_thread();
    // Posts one body until it is accepted; false at another status or a connection error.
    const auto post = [&](Connection& c, const std::string& body) {
      try {
        for (;;) {
          const auto answer = c.request(http::verb::post, "/api/v1/scans", body);
          if (answer.status >= 200 && answer.status < 300) return true;
          if (answer.status != 503) {
            fail("POST /api/v1/scans: " + std::to_string(answer.status) + " " + answer.body.substr(0, 300));
            return false;
          }
          std::this_thread::sleep_for(kRetryPause);
        }
      } catch (const std::exception& e) {
        fail(std::string("connection: ") + e.what());
        return false;
      }
    };
    for (auto _ : state) {
      std::atomic<bool> done{false};
      std::vector<std::size_t> accepted(static_cast<std::size_t>(robots), 0);
      std::vector<std::thread> flooders;
      for (int k = 1; k < robots; ++k)
        flooders.emplace_back([&, k] {
          const auto& mine = bodies[static_cast<std::size_t>(k)];
          for (std::size_t i = 0; !done; ++i) {
            if (!post(*connections[static_cast<std::size_t>(k)], mine[i % mine.size()])) return;
            ++accepted[static_cast<std::size_t>(k)];
          }
        });
      const auto start = Clock::now();
      auto last_sent = start;
      for (std::size_t i = 0; i < paced_scans; ++i) {
        const auto slot = start + i * kPacedPeriod;
        std::this_thread::sleep_until(slot);
        last_sent = Clock::now();
        if (last_sent - slot > std::chrono::milliseconds(1)) ++late;
        if (!post(*connections[0], bodies[0][i % bodies[0].size()])) break;
        paced_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - last_sent).count());
      }
      paced_span_s = std::chrono::duration<double>(last_sent - start).count();
      done = true;
      for (auto& t : flooders) t.join();
      for (int k = 1; k < robots; ++k) flooded += accepted[static_cast<std::size_t>(k)];
    }
    wmd_cpu_s = wmd.cpu_seconds() - cpu_before;
    const std::size_t all = flooded + paced_ms.size();
    beams = static_cast<double>(all) * beams_per_scan;
    if (all > 0) print_cpu_by_thread(*label + ", one at 40 Hz", robots, wmd, threads_before, wmd_cpu_s, all, beams);
    connections.clear();
    if (!error.empty()) return state.SkipWithError(error.c_str());
    if (!wmd.stop()) return state.SkipWithError("wmd did not exit 0 on SIGTERM");
  } catch (const std::exception& e) {
    return state.SkipWithError(e.what());
  }
  const std::size_t all = flooded + paced_ms.size();
  std::sort(paced_ms.begin(), paced_ms.end());
  state.SetItemsProcessed(static_cast<std::int64_t>(all));
  state.SetLabel(*label);
  state.counters["beams_per_s"] = benchmark::Counter(beams, benchmark::Counter::kIsRate);
  state.counters["flood_scans_per_s"] = benchmark::Counter(static_cast<double>(flooded), benchmark::Counter::kIsRate);
  state.counters["paced_scans"] = static_cast<double>(paced_ms.size());
  // The pace kept: scans after the first over the time from the first post to the last; 40 when every post went
  // at its slot.
  state.counters["paced_hz"] = paced_span_s > 0 ? static_cast<double>(paced_ms.size() - 1) / paced_span_s : 0.0;
  state.counters["paced_late"] = static_cast<double>(late);  // posts sent more than 1 ms after their slot
  state.counters["paced_p50_ms"] = quantile(paced_ms, 0.50);
  state.counters["paced_p99_ms"] = quantile(paced_ms, 0.99);
  state.counters["paced_max_ms"] = paced_ms.empty() ? 0.0 : paced_ms.back();
  state.counters["cpu_ns_per_beam"] = beams == 0 ? 0.0 : 1e9 * wmd_cpu_s / beams;
}

// Several maps of one wmd busy at once: `maps` maps (m0, m1, ...), each fed the whole log by its own kRobotsPerMap
// robots. With `held`, a map "held" beside them has its SQLite file's write lock taken by another connection for the
// whole run and one robot posting to it, stuck: the figure to compare with one map alone is what a stalled floor
// costs the others. Counters: scans/s over all maps, and wmd's CPU per scan.
constexpr int kRobotsPerMap = 4;

void ingest_maps(benchmark::State& state, const std::vector<wm::logs::LogScan>* scans, bool held) {
  const int maps = static_cast<int>(state.range(0));
  const auto bodies = robot_bodies(*scans, kRobotsPerMap);
  std::size_t accepted = 0;
  double wmd_cpu_s = 0;
  sqlite3* lock = nullptr;
  try {
    WmdProcess wmd({});
    Connection admin(wmd.port());
    std::vector<std::string> ids;
    for (int m = 0; m < maps; ++m) ids.push_back("m" + std::to_string(m));
    if (held) ids.push_back("held");
    for (const auto& id : ids)
      if (admin.request(http::verb::post, "/api/v1/maps", nlohmann::json{{"id", id}}.dump()).status != 201)
        return state.SkipWithError(("POST /api/v1/maps " + id + " failed").c_str());
    std::unique_ptr<Connection> stuck;
    std::thread stuck_robot;
    if (held) {
      if (sqlite3_open((wmd.dir() / "bench.db.maps" / "held.db").string().c_str(), &lock) != SQLITE_OK ||
          sqlite3_exec(lock, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) != SQLITE_OK)
        return state.SkipWithError("cannot take the held map's write lock");
      stuck = std::make_unique<Connection>(wmd.port());
      stuck_robot = std::thread([&] {
        try {
          stuck->request(http::verb::post, "/api/v1/maps/held/scans", bodies[0][0]);
        } catch (const std::exception&) {
          // answered (a 503 after the store's 5 s) or cut when wmd stops: either way it stalled until then
        }
      });
    }
    std::vector<std::unique_ptr<Connection>> connections;
    for (int k = 0; k < maps * kRobotsPerMap; ++k) connections.push_back(std::make_unique<Connection>(wmd.port()));
    std::string error;
    const double cpu_before = wmd.cpu_seconds();
    for (auto _ : state) {
      std::vector<RobotTally> tallies(connections.size());
      std::atomic<bool> failed{false};
      std::mutex error_mutex;
      std::vector<std::thread> threads;
      for (std::size_t k = 0; k < tallies.size(); ++k)
        threads.emplace_back(run_robot, std::ref(*connections[k]), std::cref(bodies[k % kRobotsPerMap]),
                             std::ref(tallies[k]), std::ref(failed), std::ref(error), std::ref(error_mutex),
                             "/api/v1/maps/" + ids[k / kRobotsPerMap] + "/scans");
      for (auto& t : threads) t.join();
      for (const auto& t : tallies) accepted += t.accepted;
      if (failed) break;
    }
    wmd_cpu_s = wmd.cpu_seconds() - cpu_before;
    if (lock) {
      sqlite3_exec(lock, "COMMIT", nullptr, nullptr, nullptr);
      sqlite3_close(lock);
      lock = nullptr;
    }
    if (stuck_robot.joinable()) stuck_robot.join();
    if (!error.empty()) return state.SkipWithError(error.c_str());
  } catch (const std::exception& e) {
    if (lock) sqlite3_close(lock);
    return state.SkipWithError(e.what());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(accepted));
  state.counters["maps"] = maps;
  state.counters["scans"] = static_cast<double>(accepted);
  state.counters["cpu_ms_per_scan"] = accepted == 0 ? 0.0 : 1000.0 * wmd_cpu_s / static_cast<double>(accepted);
  std::fprintf(stderr, "wmd CPU per scan, %d map(s) busy%s: %.3f ms\n", maps, held ? " beside a held one" : "",
               accepted == 0 ? 0.0 : 1000.0 * wmd_cpu_s / static_cast<double>(accepted));
}

// A raw SQLite writer: `rows_per_transaction` inserts of `payload` per commit, WAL and synchronous=FULL as wmd's
// --sync full.
void sqlite_commits(benchmark::State& state, const std::string* payload, int rows_per_transaction) {
  TempDir dir;
  sqlite3* db = nullptr;
  const auto check = [&](int rc, const char* what) {
    if (rc == SQLITE_OK || rc == SQLITE_DONE || rc == SQLITE_ROW) return true;
    state.SkipWithError((std::string(what) + ": " + sqlite3_errmsg(db)).c_str());
    return false;
  };
  sqlite3_stmt* insert = nullptr;
  if (check(sqlite3_open((dir.path() / "raw.db").string().c_str(), &db), "open") &&
      check(sqlite3_exec(db,
                         "PRAGMA journal_mode=WAL; PRAGMA synchronous=FULL;"
                         "CREATE TABLE scans(id INTEGER PRIMARY KEY, body BLOB NOT NULL);",
                         nullptr, nullptr, nullptr),
            "schema") &&
      check(sqlite3_prepare_v2(db, "INSERT INTO scans(body) VALUES (?)", -1, &insert, nullptr), "prepare")) {
    for (auto _ : state) {
      bool ok = check(sqlite3_exec(db, "BEGIN", nullptr, nullptr, nullptr), "begin");
      for (int i = 0; ok && i < rows_per_transaction; ++i) {
        sqlite3_bind_blob(insert, 1, payload->data(), static_cast<int>(payload->size()), SQLITE_STATIC);
        ok = check(sqlite3_step(insert), "insert") && check(sqlite3_reset(insert), "reset");
      }
      if (!ok || !check(sqlite3_exec(db, "COMMIT", nullptr, nullptr, nullptr), "commit")) break;
    }
  }
  sqlite3_finalize(insert);
  sqlite3_close(db);
  state.SetItemsProcessed(state.iterations() * rows_per_transaction);
  state.counters["commits_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["payload_bytes"] = static_cast<double>(payload->size());
}

const char* ingest_family(bool baseline) { return baseline ? "BM_Ingest_Baseline" : "BM_Ingest"; }

// A private PostgreSQL server for the run (tests/support/postgres.sh), started on first use, stopped at exit.
class PostgresServer {
 public:
  PostgresServer() {
    const std::string command = script() + " start " + dir_.path().string();
    FILE* out = ::popen(command.c_str(), "r");
    char line[512] = {};
    const bool read = out && std::fgets(line, sizeof line, out) != nullptr;
    const int status = out ? ::pclose(out) : -1;
    uri_ = read ? std::string(line) : std::string();
    while (!uri_.empty() && uri_.back() == '\n') uri_.pop_back();
    if (status != 0 || uri_.empty()) throw std::runtime_error("PostgreSQL did not start: " + command);
  }
  ~PostgresServer() {
    [[maybe_unused]] const int ignored = std::system((script() + " stop " + dir_.path().string()).c_str());
  }
  PostgresServer(const PostgresServer&) = delete;
  PostgresServer& operator=(const PostgresServer&) = delete;
  const std::string& uri() const { return uri_; }

 private:
  static std::string script() { return std::string(WM_SOURCE_DIR) + "/tests/support/postgres.sh"; }
  TempDir dir_;
  std::string uri_;
};

const PostgresServer& postgres() {
  static const auto server = std::make_unique<PostgresServer>();
  return *server;
}

// BM_Ingest with the store in PostgreSQL, a fresh schema each run.
void ingest_postgres(benchmark::State& state, const std::vector<wm::logs::LogScan>* scans) {
  static int runs = 0;
  std::vector<std::string> args;
  try {
    args = {"--store", postgres().uri(), "--store-schema",
            "bench_" + std::to_string(::getpid()) + "_" + std::to_string(++runs)};
  } catch (const std::exception& e) {
    return state.SkipWithError(e.what());
  }
  const std::string binary = WM_WMD, label = "postgresql";
  ingest(state, scans, &args, &binary, &label);
}

// A raw PostgreSQL writer: one insert of `payload` (bytea) per transaction, as the store commits a scan.
void postgres_commits(benchmark::State& state, const std::string* payload) {
  PGconn* conn = nullptr;
  try {
    conn = PQconnectdb(postgres().uri().c_str());
  } catch (const std::exception& e) {
    return state.SkipWithError(e.what());
  }
  const auto run = [&](const char* sql) {
    PGresult* r = PQexec(conn, sql);
    const bool ok = PQresultStatus(r) == PGRES_COMMAND_OK;
    if (!ok) state.SkipWithError((std::string(sql) + ": " + PQerrorMessage(conn)).c_str());
    PQclear(r);
    return ok;
  };
  const std::string table = "raw_" + std::to_string(::getpid());
  if (PQstatus(conn) == CONNECTION_OK &&
      run(("CREATE TABLE " + table + "(id BIGSERIAL PRIMARY KEY, body BYTEA NOT NULL)").c_str())) {
    const std::string insert = "INSERT INTO " + table + "(body) VALUES ($1)";
    const char* values[] = {payload->data()};
    const int lengths[] = {static_cast<int>(payload->size())}, formats[] = {1};
    for (auto _ : state) {
      if (!run("BEGIN")) break;
      PGresult* r = PQexecParams(conn, insert.c_str(), 1, nullptr, values, lengths, formats, 0);
      const bool ok = PQresultStatus(r) == PGRES_COMMAND_OK;
      PQclear(r);
      if (!ok || !run("COMMIT")) break;
    }
    run(("DROP TABLE " + table).c_str());
  } else if (PQstatus(conn) != CONNECTION_OK) {
    state.SkipWithError(PQerrorMessage(conn));
  }
  PQfinish(conn);
  state.SetItemsProcessed(state.iterations());
  state.counters["commits_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// A set of scans posted by the beam-count benchmarks: a real log, or a drive ray-cast in a floor plan.
struct ScanSet {
  std::string name;  // in the benchmark's name: letters, digits and '_'
  std::vector<wm::logs::LogScan> scans;
};

// `count` scans of a 1 081-beam 270° scanner driving through a plan at 40 Hz.
std::vector<wm::logs::LogScan> dense_scans(const std::vector<wm::raycast::PlanLine>& lines, std::size_t count) {
  std::vector<wm::logs::LogScan> scans;
  for (auto& scan : wm::bench::dense_drive(lines, count)) {
    scans.push_back({scans.size() + 1, 0.025 * static_cast<double>(scans.size()), std::move(scan)});
  }
  return scans;
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The data sets of the beam-count benchmarks: CSAIL's 360-beam log (when this machine has it) and dense drives in two
// plans of different kinds, a university floor (GDC1, 1 289 lines) and an office with its furniture (Open-RMF).
std::deque<ScanSet> beam_sets(std::size_t count, bool both_plans) {
  std::deque<ScanSet> sets;
  const fs::path csail = fs::path(WM_SHARED_DATA_DIR) / "carmen" / "csail-corrected.log.gz";
  if (fs::exists(csail)) sets.push_back({"csail360", read_scans(csail, count)});
  const fs::path plans = fs::path(WM_SOURCE_DIR) / "tests" / "data" / "plans";
  sets.push_back(
      {"gdc1_1081", dense_scans(wm::raycast::read_vectormap((plans / "GDC1.vectormap.json").string()), count)});
  if (both_plans) {
    const auto office = wm::apriori::import_rmf_building(read_text(plans / "rmf-office.building.yaml"));
    sets.push_back({"office1081", dense_scans(wm::bench::plan_lines(office.plan), count)});
  }
  return sets;
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t scan_limit = std::getenv("WM_BENCH_QUICK") ? 200 : std::getenv("WM_BENCH_LOG") ? 2000 : SIZE_MAX;
  const fs::path log = intel_log();
  std::vector<wm::logs::LogScan> scans;
  try {
    scans = read_scans(log, scan_limit);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ingest_bench: %s\n", e.what());
    return 1;
  }
  if (scans.empty()) {
    std::fprintf(stderr, "ingest_bench: no scans in %s\n", log.c_str());
    return 1;
  }
  std::printf("ingest_bench: %zu scans of %s\n", scans.size(), log.c_str());

  const char* baseline_env = std::getenv("WM_BENCH_BASELINE_ARGS");
  const char* baseline_wmd_env = std::getenv("WM_BENCH_BASELINE_WMD");
  const bool other_build = baseline_wmd_env && *baseline_wmd_env;
  const std::vector<std::string> default_args;
  const std::vector<std::string> baseline_args = baseline_env && *baseline_env ? split_words(baseline_env)
                                                 : other_build                 ? std::vector<std::string>{}
                                                               : std::vector<std::string>{"--handler-threads", "8"};
  const std::string default_binary = WM_WMD;
  const std::string baseline_binary = other_build ? baseline_wmd_env : WM_WMD;
  std::string baseline_label = other_build ? "baseline " + baseline_binary + ":" : "baseline:";
  for (const auto& a : baseline_args) baseline_label += " " + a;
  const std::string default_label = "default";
  const std::string payload = scan_body(scans.front(), "robot-0");

  // Names end in /real_time: the ratio reporter compares a baseline only with names of the same suffix.
  benchmark::RegisterBenchmark("BM_SqliteCommit_1RowPerTxn", sqlite_commits, &payload, 1)->UseRealTime();
  benchmark::RegisterBenchmark("BM_SqliteCommit_16RowsPerTxn", sqlite_commits, &payload, 16)->UseRealTime();
  std::vector<std::pair<std::string, std::string>> ratios;
  for (const int robots : kRobotCounts) {
    for (const bool baseline : {false, true})
      benchmark::RegisterBenchmark(ingest_family(baseline), ingest, &scans, baseline ? &baseline_args : &default_args,
                                   baseline ? &baseline_binary : &default_binary,
                                   baseline ? &baseline_label : &default_label)
          ->ArgName("robots")
          ->Arg(robots)
          ->Iterations(1)
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond);
    ratios.push_back(
        {"default wmd against " + baseline_label + ", " + std::to_string(robots) + " robots",
         std::string(ingest_family(true)) + "/robots:" + std::to_string(robots) + "/iterations:1/real_time"});
  }
  ratios.push_back({"against raw SQLite, one commit per scan", "BM_SqliteCommit_1RowPerTxn/real_time"});
  // The store in PostgreSQL against the store in SQLite, and PostgreSQL's own commit rate.
  benchmark::RegisterBenchmark("BM_PostgresCommit_1RowPerTxn", postgres_commits, &payload)->UseRealTime();
  for (const int robots : {1, 4})
    benchmark::RegisterBenchmark("BM_IngestPostgres", ingest_postgres, &scans)
        ->ArgName("robots")
        ->Arg(robots)
        ->Iterations(1)
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond);
  for (const int robots : {1, 4})
    ratios.push_back({"the PostgreSQL store against the SQLite store, " + std::to_string(robots) + " robots",
                      "BM_Ingest/robots:" + std::to_string(robots) + "/iterations:1/real_time"});
  ratios.push_back({"against raw PostgreSQL, one commit per scan", "BM_PostgresCommit_1RowPerTxn/real_time"});
  // Maps side by side: one, four, and one beside a map whose writer is held (against one map alone).
  for (const int maps : {1, 4})
    benchmark::RegisterBenchmark("BM_IngestMaps", ingest_maps, &scans, false)
        ->ArgName("maps")
        ->Arg(maps)
        ->Iterations(1)
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("BM_IngestMapsBesideAHeldMap", ingest_maps, &scans, true)
      ->ArgName("maps")
      ->Arg(1)
      ->Iterations(1)
      ->UseRealTime()
      ->Unit(benchmark::kMillisecond);
  ratios.push_back({"against one map alone (4 robots)", "BM_IngestMaps/maps:1/iterations:1/real_time"});

  // Scans of more beams: CSAIL's 360 and a 1 081-beam scanner in two plans, 1 and 16 robots, against the Intel log's
  // 180 beams above (16 robots, scans/s; beams/s and CPU per beam are counters); then one robot at 40 Hz among 15
  // flooding robots. WM_BENCH_QUICK: fewer scans, one plan, 16 robots only.
  const bool quick = std::getenv("WM_BENCH_QUICK") != nullptr;
  std::deque<ScanSet> sets;
  try {
    const auto start = Clock::now();
    sets = beam_sets(quick ? 160 : 1440, !quick);
    std::printf("ingest_bench: dense drives ray-cast in %.1f s:",
                std::chrono::duration<double>(Clock::now() - start).count());
    for (const auto& set : sets) {
      // How far the drive went and how many beams hit something: a drive stuck in a corner would show here.
      double driven_m = 0, returns = 0;
      for (std::size_t i = 0; i < set.scans.size(); ++i) {
        const auto& scan = set.scans[i].scan;
        if (i > 0) {
          const auto& before = set.scans[i - 1].scan.sensor_pose;
          driven_m += std::hypot(scan.sensor_pose.x_m - before.x_m, scan.sensor_pose.y_m - before.y_m);
        }
        for (double r : scan.ranges_m) returns += std::isfinite(r) && r < scan.range_max_m ? 1 : 0;
      }
      std::printf(" %s %zu scans of %zu beams, %.0f m, %.0f %% returns;", set.name.c_str(), set.scans.size(),
                  set.scans.empty() ? 0 : set.scans.front().scan.ranges_m.size(), driven_m,
                  100.0 * returns / static_cast<double>(std::max<std::size_t>(beams_of(set.scans), 1)));
    }
    std::printf("\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ingest_bench: %s\n", e.what());
    return 1;
  }
  std::deque<std::string> labels;
  for (const auto& set : sets) {
    labels.push_back(set.name);
    for (const int robots : quick ? std::vector<int>{16} : std::vector<int>{1, 16})
      benchmark::RegisterBenchmark(("BM_IngestBeams_" + set.name).c_str(), ingest, &set.scans, &default_args,
                                   &default_binary, &labels.back())
          ->ArgName("robots")
          ->Arg(robots)
          ->Iterations(1)
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond);
  }
  for (std::size_t i = 0; i < sets.size(); ++i) {
    if (sets[i].name.find("1081") == std::string::npos) continue;
    benchmark::RegisterBenchmark(("BM_IngestPaced40HzAmongFlooders_" + sets[i].name).c_str(), ingest_paced,
                                 &sets[i].scans, std::size_t{quick ? 20u : 240u}, &labels[i])
        ->ArgName("robots")
        ->Arg(kFlooders + 1)
        ->Iterations(1)
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond);
  }
  ratios.push_back(
      {"scans/s against the Intel log's 180 beams, 16 robots", "BM_Ingest/robots:16/iterations:1/real_time"});
  return wm::bench::run_with_ratios(argc, argv, ratios);
}
