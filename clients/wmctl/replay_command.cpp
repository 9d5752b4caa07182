// wmctl replay: posts the laser scans of a CARMEN log to wmd.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <string>
#include <thread>

#include "clients/wmctl/commands.h"
#include "logs/carmen_log_reader.h"
#include "logs/scan_body.h"

namespace wm::wmctl {
namespace {

json scan_json(const fusion::LaserScan& scan, const std::string& source, double stamp, double sigma_xy,
               double sigma_theta) {
  json body = logs::laser_scan_body(scan, source, stamp);
  // The logs' corrected poses are good, not exact: the matcher's tolerances and the calibration figure count on
  // the pose uncertainty being part of every scan line's covariance.
  body["pose_cov"] = {{sigma_xy * sigma_xy, 0, 0}, {0, sigma_xy * sigma_xy, 0}, {0, 0, sigma_theta * sigma_theta}};
  return body;
}

// A number > 0 given as `flag`'s value; `what` says what was expected.
double positive(const std::string& flag, const std::string& value, const std::string& what) {
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (*end != '\0' || !(v > 0)) throw UsageError(flag + ": expected " + what);
  return v;
}

// The replay's settings, from the command line.
struct ReplayOptions {
  std::size_t limit = 0;  // scans to post at most; 0: all
  std::size_t every = 1;  // post every K-th scan
  double rate_hz = 0;     // scans per second at most; 0: as fast as the server takes them
  double offset_x_m = 0, offset_y_m = 0;
  std::string source;                                  // the robot name the scans are posted under
  double sigma_xy_m = 0.03, sigma_theta_rad = 0.0087;  // 3 cm, 0.5°
  double usable_range_m = 0;                           // sent as the scans' usable_range when > 0
  logs::CarmenReaderOptions reader;
};

ReplayOptions replay_options(const Invocation& in) {
  ReplayOptions o;
  o.source = std::filesystem::path(in.operands[0]).stem().string();
  for (const auto& [flag, value] : in.flags) {
    if (flag == "--limit") {
      o.limit = static_cast<std::size_t>(parse_count(value));
    } else if (flag == "--every") {
      o.every = static_cast<std::size_t>(parse_count(value));
    } else if (flag == "--source") {
      o.source = value;
    } else if (flag == "--rate") {
      o.rate_hz = positive(flag, value, "scans per second > 0");
    } else if (flag == "--offset") {
      if (std::sscanf(value.c_str(), "%lf,%lf", &o.offset_x_m, &o.offset_y_m) != 2 || !std::isfinite(o.offset_x_m) ||
          !std::isfinite(o.offset_y_m))
        throw UsageError("--offset: expected DX,DY in metres");
    } else if (flag == "--pose-sigma") {
      if (std::sscanf(value.c_str(), "%lf,%lf", &o.sigma_xy_m, &o.sigma_theta_rad) != 2 || !(o.sigma_xy_m >= 0) ||
          !(o.sigma_theta_rad >= 0))
        throw UsageError("--pose-sigma: expected SIGMA_XY,SIGMA_THETA in metres and radians, e.g. 0.03,0.0087");
    } else if (flag == "--range-max") {
      o.reader.flaser_range_max_m = positive(flag, value, "metres > 0");
    } else if (flag == "--usable-range") {
      o.usable_range_m = positive(flag, value, "metres > 0");
    }
  }
  return o;
}

}  // namespace

// Posts a log's scans in file order (timestamps in real logs go backwards) and reports the rate.
int replay(const Invocation& in) {
  const ReplayOptions o = replay_options(in);
  const std::string& log = in.operands[0];
  logs::CarmenLogReader reader(log, o.reader);
  const auto start = std::chrono::steady_clock::now();
  std::size_t read = 0, posted = 0;
  int shown = -1;
  const bool progress_bar = !in.raw_json && ::isatty(STDERR_FILENO);
  while (auto scan = reader.next()) {
    if (read++ % o.every != 0) continue;
    scan->scan.sensor_pose.x_m += o.offset_x_m;  // e.g. to place a log beside a floor plan it does not belong to
    scan->scan.sensor_pose.y_m += o.offset_y_m;
    if (o.rate_hz > 0)
      std::this_thread::sleep_until(start + std::chrono::duration<double>(static_cast<double>(posted) / o.rate_hz));
    auto message = scan_json(scan->scan, o.source, scan->timestamp_s, o.sigma_xy_m, o.sigma_theta_rad);
    if (o.usable_range_m > 0) message["usable_range"] = o.usable_range_m;
    const auto body = message.dump();
    parse_answer(in.client.request("POST", "/api/v1/scans", body, "application/json", in.token));
    ++posted;
    const int percent = static_cast<int>(100.0 * reader.progress());
    if (progress_bar && percent != shown) {
      shown = percent;
      std::cerr << "\r[" << std::string(static_cast<std::size_t>(percent / 2), '#')
                << std::string(static_cast<std::size_t>(50 - percent / 2), ' ') << "] " << percent << "%  " << posted
                << " scans" << std::flush;
    }
    if (o.limit && posted >= o.limit) break;
  }
  if (progress_bar) std::cerr << "\n";
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto health = parse_answer(in.client.request("GET", "/api/v1/health"));
  const auto decisions = health["last_decision_seq"].get<std::size_t>();
  const json summary = {{"log", log},
                        {"scans_read", read},
                        {"scans_posted", posted},
                        {"seconds", seconds},
                        {"scans_per_second", seconds > 0 ? static_cast<double>(posted) / seconds : 0.0},
                        {"lines", reader.lines_read()},
                        {"decisions_total", decisions}};
  if (in.raw_json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::cout << "replayed " << posted << " of " << read << " scans from " << log << " in " << std::fixed
              << std::setprecision(1) << seconds << " s (" << summary["scans_per_second"].get<double>()
              << " scans/s); the map now has " << health["elements"] << " elements, " << decisions
              << " decisions logged\n";
  }
  return kExitOk;
}

}  // namespace wm::wmctl
