// wmctl: the command-line client of wmd, over the HTTP/JSON API only.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <thread>
#include <cmath>
#include <cstdlib>
#include <unistd.h>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "clients/logs/carmen_log_reader.h"
#include "clients/wmctl/http_client.h"

namespace {

using nlohmann::json;

constexpr int kExitOk = 0;
constexpr int kExitServerError = 1;  // the server answered with an error status
constexpr int kExitUsage = 2;
constexpr int kExitUnreachable = 3;

const char* kUsage =
    "usage: wmctl [--server URL] [--token TOKEN] [--json] COMMAND\n"
    "commands:\n"
    "  health                         server status, counts and loaded rules\n"
    "  floorplan load FILE [--mapping M.json] [--units U] [--level L]\n"
    "                                 load a floor plan: JSON, AMRL vector map, DXF, Open-RMF building.yaml\n"
    "  floorplan show                 print the loaded floor plan\n"
    "  primitives post FILE           post line primitives (JSON, as POST /api/v1/primitives), print decisions\n"
    "  map [--format dxf|geojson --out FILE]   objects and observed elements (or export them)\n"
    "  report                         as-built report: what was confirmed, moved, never observed\n"
    "  decisions [--since SEQ] [--limit N] [--element ID]   the decision log\n"
    "  explain ID                     history of an element or object: observations, rules, numbers\n"
    "  rules                          loaded rule files, checksums, last reload error\n"
    "  rules reload                   reload the rules directory now (atomic; needs the token if set)\n"
    "  rules dry-run FILE [--last N]  re-decide the last N decisions with FILE in place of its namesake\n"
    "  query GOAL [--max N]           read-only Prolog query against the knowledge base\n"
    "  replay LOG [--limit N] [--every K] [--rate HZ] [--offset DX,DY] [--source NAME] [--range-max M]\n"
    "             [--pose-sigma XY,THETA]\n"
    "                                 post the laser scans of a CARMEN log (FLASER / ROBOTLASER1, plain or .gz)\n"
    "                                 in line order, with a progress bar and a summary\n"
    "  grid --out FILE.pgm [--layer L] [--bbox x0,y0,x1,y1]\n"
    "                                 save a grid layer (bayes, ds_belief, ds_plausibility, ds_conflict) as\n"
    "                                 PGM; with the bayes layer also FILE.yaml for ROS map_server\n"
    "  grid extract                   run the grid line extractor now; its lines are decided like primitives\n"
    "options:\n"
    "  --server URL   default http://127.0.0.1:8080 (or $WMCTL_SERVER)\n"
    "  --json         print the server's JSON as it came (for scripts)\n";

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Calls handle(flag, value) for each "--flag value" pair of words[first..]; a flag without its value throws
// UsageError(usage), one that handle() does not know (returns false) UsageError(unknown).
template <typename F>
void for_each_option(const std::vector<std::string>& words, std::size_t first, const std::string& usage,
                     const std::string& unknown, F&& handle) {
  for (std::size_t i = first; i < words.size(); i += 2) {
    if (i + 1 >= words.size()) throw UsageError(usage);
    if (!handle(words[i], words[i + 1])) throw UsageError(unknown);
  }
}

struct ServerError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw UsageError("cannot read '" + path + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void write_file(const std::string& path, const std::string& data) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out || !(out << data)) throw UsageError("cannot write '" + path + "'");
}

json parse_answer(const wm::client::HttpResult& r) {
  json body = json::parse(r.body, nullptr, false);
  if (r.status >= 400) {
    std::string message = "server answered " + std::to_string(r.status);
    if (body.is_object() && body.contains("error"))
      message += " " + body.value("error", "") + ": " + body.value("detail", "");
    else
      message += ": " + r.body.substr(0, 200);
    throw ServerError(message);
  }
  if (body.is_discarded()) throw ServerError("server answered something that is not JSON");
  return body;
}

std::string fixed(double v, int digits = 3) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << v;
  return s.str();
}

std::string point(const json& p) { return "(" + fixed(p[0].get<double>()) + ", " + fixed(p[1].get<double>()) + ")"; }

std::string optional_text(const json& v) { return v.is_null() ? "-" : v.get<std::string>(); }

void print_decision(const json& d) {
  std::cout << "#" << d["seq"].get<long long>() << "  " << std::left << std::setw(13) << d["action"].get<std::string>()
            << std::setw(24) << d["rule"].get<std::string>() << " element " << std::setw(12) << optional_text(d["element"])
            << " object " << std::setw(12) << optional_text(d["object"]) << (d["fallback"].get<bool>() ? " FALLBACK" : "")
            << "\n      " << d["explanation"].get<std::string>() << "\n";
}

void print_map(const json& m) {
  std::cout << "map version " << m["version"] << ", plan '" << m["plan"].get<std::string>() << "': " << m["objects"].size()
            << " objects, " << m["elements"].size() << " observed elements\n";
  for (const auto& o : m["objects"]) {
    std::string attributes;
    for (const auto& a : o["attributes"]) attributes += (attributes.empty() ? "" : ",") + a.get<std::string>();
    std::cout << "  object " << std::left << std::setw(14) << o["id"].get<std::string>() << std::setw(10)
              << o["kind"].get<std::string>() << " [" << attributes << "] pose (" << fixed(o["pose"]["x"].get<double>()) << ", "
              << fixed(o["pose"]["y"].get<double>()) << ", " << fixed(o["pose"]["theta"].get<double>(), 4) << ") edges "
              << o["edges"].size() << ", confirmed " << o["confirmations"] << ", adjusted " << o["adjustments"] << "\n";
  }
  for (const auto& e : m["elements"])
    std::cout << "  element " << std::left << std::setw(8) << e["id"].get<std::string>() << point(e["p0"]) << " -> "
              << point(e["p1"]) << "  support " << e["support"] << ", source " << e["source"].get<std::string>() << "\n";
}

std::int64_t parse_count(const std::string& text) {
  try {
    std::size_t used = 0;
    const auto n = std::stoll(text, &used);
    if (used == text.size() && n > 0) return n;
  } catch (const std::exception&) {
  }
  throw UsageError("expected a positive count, got '" + text + "'");
}

// Element ids are "e<n>"; everything else is taken as a CAD object id.
std::string history_target(const std::string& id) {
  const bool element = id.size() > 1 && id[0] == 'e' && id.find_first_not_of("0123456789", 1) == std::string::npos;
  return std::string(element ? "/api/v1/elements/" : "/api/v1/objects/") + id + "/history";
}

std::string numbers(const json& state) {
  std::ostringstream out;
  out << std::setprecision(4);
  if (state.contains("rho")) {
    out << "rho " << state["rho"].get<double>() << " m, phi " << state["phi"].get<double>() << " rad, sigma_rho "
        << std::sqrt(state["cov"][0][0].get<double>()) << " m, sigma_phi " << std::sqrt(state["cov"][1][1].get<double>())
        << " rad";
  } else if (state.contains("pose")) {
    out << "pose (" << state["pose"]["x"].get<double>() << ", " << state["pose"]["y"].get<double>() << ", "
        << state["pose"]["theta"].get<double>() << "), sigma_xy " << std::sqrt(state["pose_cov"][0][0].get<double>())
        << " m";
  }
  return out.str();
}

void print_history(const json& r) {
  std::cout << r["id"].get<std::string>() << (r["exists"].get<bool>() ? "" : " (no longer in the map)") << ": "
            << r["decisions"].size() << " decisions\n";
  for (const auto& d : r["decisions"]) {
    print_decision(d);
    std::cout << "      observation " << d["observation"] << " by " << d["source"].get<std::string>() << " ("
              << d["origin"].get<std::string>() << ", sensor " << d["sensor"].get<std::string>() << ")";
    if (!d["mahalanobis_sq"].is_null()) std::cout << ", d2 " << d["mahalanobis_sq"].get<double>();
    std::cout << "\n";
    if (d.contains("before")) std::cout << "      before: " << numbers(d["before"]) << "\n";
    if (d.contains("after")) std::cout << "      after:  " << numbers(d["after"]) << "\n";
  }
}

void print_rules(const json& r) {
  std::cout << "generation " << r["generation"] << "\n";
  for (const auto& f : r["files"])
    std::cout << "  " << f["path"].get<std::string>() << "  sha256 " << f["checksum"].get<std::string>().substr(0, 12) << "\n";
  if (!r["last_error"].get<std::string>().empty()) std::cout << "last error:\n" << r["last_error"].get<std::string>() << "\n";
}

void print_dry_run(const json& r) {
  std::cout << r["redecided"] << " decisions re-decided with " << r["file"].get<std::string>() << ": " << r["changed"]
            << " would change\n";
  for (const auto& c : r["changes"]) {
    const auto& old = c["recorded"];
    const auto& now = c["candidate"];
    std::cout << "  #" << old["seq"] << " " << old["action"].get<std::string>() << " by " << old["rule"].get<std::string>()
              << "  ->  " << now["action"].get<std::string>() << " by " << now["rule"].get<std::string>() << "\n      "
              << now["explanation"].get<std::string>() << "\n";
  }
}

void print_query(const json& r) {
  if (r["solutions"].empty()) std::cout << "false.\n";
  for (const auto& solution : r["solutions"]) {
    if (solution.empty()) {
      std::cout << "true.\n";
      continue;
    }
    std::string line;
    for (const auto& [name, value] : solution.items())
      line += (line.empty() ? "" : ", ") + name + " = " + (value.is_string() ? value.get<std::string>() : value.dump());
    std::cout << line << "\n";
  }
  if (r["truncated"].get<bool>()) std::cout << "(more solutions; raise --max)\n";
}

json scan_json(const wm::fusion::LaserScan& scan, const std::string& source, double stamp, double sigma_xy, double sigma_theta) {
  json ranges = json::array();
  for (const double r : scan.ranges_m) ranges.push_back(std::isfinite(r) ? json(r) : json(nullptr));
  return {{"sensor", "laser"},
          {"source", source},
          {"stamp", stamp},
          {"pose", {{"x", scan.sensor_pose.x_m}, {"y", scan.sensor_pose.y_m}, {"theta", scan.sensor_pose.theta_rad}}},
          {"angle_min", scan.angle_min_rad},
          {"angle_increment", scan.angle_increment_rad},
          {"ranges", std::move(ranges)},
          {"range_min", scan.range_min_m},
          {"range_max", scan.range_max_m},
          {"sigma_range", scan.sigma_range_m},
          // The logs' corrected poses are good, not exact: without this the lines of one wall seen twice would
          // fail the χ² gate by a centimetre and pile up as separate elements.
          {"pose_cov", {{sigma_xy * sigma_xy, 0, 0}, {0, sigma_xy * sigma_xy, 0}, {0, 0, sigma_theta * sigma_theta}}}};
}

// Posts a log's scans in file order (timestamps in real logs go backwards) and reports the rate.
int replay(const wm::client::HttpClient& client, const std::string& token, const std::vector<std::string>& words,
           bool raw_json) {
  std::size_t limit = 0, every = 1;
  double sigma_xy = 0.03, sigma_theta = 0.0087;  // 3 cm, 0.5°
  double rate_hz = 0, offset_x = 0, offset_y = 0;
  std::string source = std::filesystem::path(words[1]).stem().string();
  wm::logs::CarmenReaderOptions options;
  for_each_option(words, 2, "replay LOG [--limit N] [--every K] [--source NAME] [--range-max M]",
                  "replay takes --limit, --every, --rate, --offset, --source, --range-max, --pose-sigma",
                  [&](const std::string& flag, const std::string& value) {
    if (flag == "--limit") limit = static_cast<std::size_t>(parse_count(value));
    else if (flag == "--every") every = static_cast<std::size_t>(parse_count(value));
    else if (flag == "--source") source = value;
    else if (flag == "--rate") {
      char* end = nullptr;
      rate_hz = std::strtod(value.c_str(), &end);
      if (*end != '\0' || !(rate_hz > 0)) throw UsageError("--rate: expected scans per second > 0");
    } else if (flag == "--offset") {
      if (std::sscanf(value.c_str(), "%lf,%lf", &offset_x, &offset_y) != 2 || !std::isfinite(offset_x) ||
          !std::isfinite(offset_y))
        throw UsageError("--offset: expected DX,DY in metres");
    } else if (flag == "--pose-sigma") {
      if (std::sscanf(value.c_str(), "%lf,%lf", &sigma_xy, &sigma_theta) != 2 || !(sigma_xy >= 0) || !(sigma_theta >= 0))
        throw UsageError("--pose-sigma: expected SIGMA_XY,SIGMA_THETA in metres and radians, e.g. 0.03,0.0087");
    } else if (flag == "--range-max") {
      char* end = nullptr;
      options.flaser_range_max_m = std::strtod(value.c_str(), &end);
      if (*end != '\0' || !(options.flaser_range_max_m > 0)) throw UsageError("--range-max: expected metres > 0");
    } else {
      return false;
    }
    return true;
  });
  wm::logs::CarmenLogReader reader(words[1], options);
  const auto start = std::chrono::steady_clock::now();
  std::size_t read = 0, posted = 0, decisions = 0;
  int shown = -1;
  const bool progress_bar = !raw_json && ::isatty(STDERR_FILENO);
  while (auto scan = reader.next()) {
    if (read++ % every != 0) continue;
    scan->scan.sensor_pose.x_m += offset_x;  // e.g. to place a log beside a floor plan it does not belong to
    scan->scan.sensor_pose.y_m += offset_y;
    if (rate_hz > 0) std::this_thread::sleep_until(start + std::chrono::duration<double>(static_cast<double>(posted) / rate_hz));
    parse_answer(client.request("POST", "/api/v1/scans", scan_json(scan->scan, source, scan->timestamp_s, sigma_xy, sigma_theta).dump(),
                                "application/json", token));
    ++posted;
    const int percent = static_cast<int>(100.0 * reader.progress());
    if (progress_bar && percent != shown) {
      shown = percent;
      std::cerr << "\r[" << std::string(static_cast<std::size_t>(percent / 2), '#')
                << std::string(static_cast<std::size_t>(50 - percent / 2), ' ') << "] " << percent << "%  " << posted
                << " scans" << std::flush;
    }
    if (limit && posted >= limit) break;
  }
  if (progress_bar) std::cerr << "\n";
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto health = parse_answer(client.request("GET", "/api/v1/health"));
  decisions = health["last_decision_seq"].get<std::size_t>();
  const json summary = {{"log", words[1]},          {"scans_read", read},  {"scans_posted", posted},
                        {"seconds", seconds},        {"scans_per_second", seconds > 0 ? posted / seconds : 0.0},
                        {"lines", reader.lines_read()}, {"decisions_total", decisions}};
  if (raw_json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::cout << "replayed " << posted << " of " << read << " scans from " << words[1] << " in " << std::fixed
              << std::setprecision(1) << seconds << " s (" << summary["scans_per_second"].get<double>()
              << " scans/s); the map now has " << health["elements"] << " elements, " << decisions << " decisions logged\n";
  }
  return kExitOk;
}

int run(const std::vector<std::string>& args) {
  std::string server = std::getenv("WMCTL_SERVER") ? std::getenv("WMCTL_SERVER") : "http://127.0.0.1:8080";
  std::string token;
  bool raw_json = false;
  std::vector<std::string> words;
  for (std::size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--server" || args[i] == "--token") {
      if (i + 1 >= args.size()) throw UsageError(args[i] + " needs a value");
      std::string& target = args[i] == "--server" ? server : token;
      target = args[++i];
    } else if (args[i] == "--json") {
      raw_json = true;
    } else if (args[i] == "--help" || args[i] == "-h") {
      std::cout << kUsage;
      return kExitOk;
    } else {
      words.push_back(args[i]);
    }
  }
  if (words.empty()) throw UsageError("no command");
  const wm::client::HttpClient client(server);
  const auto emit = [&](const json& body, auto&& readable) {
    if (raw_json) std::cout << body.dump(2) << "\n";
    else readable(body);
    return kExitOk;
  };
  const std::string& command = words[0];
  if (command == "health" && words.size() == 1) {
    return emit(parse_answer(client.request("GET", "/api/v1/health")), [](const json& h) {
      std::cout << "status " << h["status"].get<std::string>() << ", map version " << h["version"] << ", plan '"
                << h["plan"].get<std::string>() << "', " << h["objects"] << " objects, " << h["elements"] << " elements\n";
      for (const auto& f : h["rules"]["files"]) std::cout << "rules: " << f["path"].get<std::string>() << "\n";
      if (!h["rules"]["last_error"].get<std::string>().empty())
        std::cout << "last rules error: " << h["rules"]["last_error"].get<std::string>() << "\n";
    });
  }
  if (command == "floorplan" && words.size() >= 3 && words[1] == "load") {
    // DXF and RMF files go in an import envelope with the options; JSON (plan or AMRL map) goes as it is.
    std::string mapping_file, units, level;
    for_each_option(words, 3, "floorplan load FILE [--mapping FILE.json] [--units m|cm|mm|in|ft] [--level NAME]",
                    "floorplan load takes --mapping, --units, --level", [&](const std::string& flag, const std::string& value) {
      if (flag == "--mapping") mapping_file = value;
      else if (flag == "--units") units = value;
      else if (flag == "--level") level = value;
      else return false;
      return true;
    });
    const std::string file = words[2];
    auto extension = std::filesystem::path(file).extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
    std::string body = read_file(file);
    if (extension == ".dxf" || extension == ".yaml" || extension == ".yml") {
      // Ordered: the mapping's rules apply in file order.
      nlohmann::ordered_json spec = {{"format", extension == ".dxf" ? "dxf" : "rmf"}, {"data", body},
                                     {"name", std::filesystem::path(file).stem().string()}};
      if (!mapping_file.empty()) {
        const auto mapping = nlohmann::ordered_json::parse(read_file(mapping_file), nullptr, false);
        if (mapping.is_discarded()) throw UsageError("'" + mapping_file + "' is not JSON");
        spec["mapping"] = mapping;
      }
      if (!units.empty()) spec["units"] = units;
      if (!level.empty()) spec["level"] = level;
      body = nlohmann::ordered_json{{"import", spec}}.dump(-1, ' ', false, json::error_handler_t::replace);
    } else if (!mapping_file.empty() || !units.empty() || !level.empty()) {
      throw UsageError("--mapping, --units and --level apply to .dxf and RMF .yaml files");
    }
    return emit(parse_answer(client.request("PUT", "/api/v1/floorplan", body, "application/json", token)),
                [](const json& r) {
                  std::cout << "loaded floor plan '" << r["name"].get<std::string>() << "': " << r["objects"] << " objects, "
                            << r["edges"] << " edges (map version " << r["version"] << ")\n";
                  if (r.contains("report")) {
                    const auto& report = r["report"];
                    for (const auto& [type, count] : report["entity_counts"].items())
                      std::cout << "  " << type << ": " << count << "\n";
                    for (const auto& layer : report["unknown_layers"])
                      std::cout << "  unknown layer (skipped): " << layer.get<std::string>() << "\n";
                    for (const auto& warning : report["warnings"]) std::cout << "  warning: " << warning.get<std::string>() << "\n";
                  }
                });
  }
  if (command == "floorplan" && words.size() == 2 && words[1] == "show") {
    const auto plan = parse_answer(client.request("GET", "/api/v1/floorplan"));
    std::cout << plan.dump(2) << "\n";
    return kExitOk;
  }
  if (command == "primitives" && words.size() == 3 && words[1] == "post") {
    return emit(parse_answer(client.request("POST", "/api/v1/primitives", read_file(words[2]), "application/json", token)),
                [](const json& r) {
                  std::cout << "observation " << r["seq"] << " applied, map version " << r["version"] << "\n";
                  for (const auto& d : r["decisions"]) print_decision(d);
                });
  }
  if (command == "map" && words.size() == 1) return emit(parse_answer(client.request("GET", "/api/v1/map")), print_map);
  if (command == "map" && words.size() == 5 && words[1] == "--format" && words[3] == "--out") {
    const auto r = client.request("GET", "/api/v1/map?format=" + words[2]);
    if (r.status != 200) parse_answer(r);
    write_file(words[4], r.body);
    std::cout << "wrote " << words[4] << " (" << r.body.size() << " bytes)\n";
    return kExitOk;
  }
  if (command == "report" && words.size() == 1) {
    return emit(parse_answer(client.request("GET", "/api/v1/report/as-built")), [](const json& r) {
      const auto& s = r["summary"];
      std::cout << "plan '" << r["plan"].get<std::string>() << "': " << s["objects"] << " objects, " << s["confirmed"]
                << " confirmed, " << s["moved"] << " moved, " << s["never_observed"] << " never observed; "
                << s["not_in_plan"] << " observed elements not in the plan\n";
      for (const auto& o : r["objects"]) {
        if (o["status"] != "moved") continue;
        std::cout << "  moved: " << o["id"].get<std::string>() << " by " << o["moved_by"]["distance"].get<double>()
                  << " m, " << o["moved_by"]["dtheta"].get<double>() << " rad\n";
      }
    });
  }
  if (command == "decisions") {
    std::string query;
    const std::string usage = "decisions takes --since SEQ, --limit N, --element ID";
    for_each_option(words, 1, usage, usage, [&](const std::string& flag, const std::string& value) {
      if (flag != "--since" && flag != "--limit" && flag != "--element") return false;
      query += (query.empty() ? "?" : "&") + flag.substr(2) + "=" + value;
      return true;
    });
    return emit(parse_answer(client.request("GET", "/api/v1/decisions" + query)), [](const json& r) {
      for (const auto& d : r["decisions"]) print_decision(d);
      std::cout << r["decisions"].size() << " decisions\n";
    });
  }
  if (command == "explain" && words.size() == 2) {
    return emit(parse_answer(client.request("GET", history_target(words[1]))), print_history);
  }
  if (command == "rules" && words.size() == 1) {
    return emit(parse_answer(client.request("GET", "/api/v1/rules")), print_rules);
  }
  if (command == "rules" && words.size() == 2 && words[1] == "reload") {
    return emit(parse_answer(client.request("POST", "/api/v1/rules/reload", "{}", "application/json", token)), [](const json& r) {
      std::cout << "rules reloaded (generation " << r["generation"] << ")\n";
      print_rules(r);
    });
  }
  if (command == "rules" && (words.size() == 3 || words.size() == 5) && words[1] == "dry-run") {
    json body = {{"file", std::filesystem::path(words[2]).filename().string()}, {"text", read_file(words[2])}};
    if (words.size() == 5) {
      if (words[3] != "--last") throw UsageError("rules dry-run FILE [--last N]");
      body["last"] = parse_count(words[4]);
    }
    return emit(parse_answer(client.request("POST", "/api/v1/rules/dry-run", body.dump(), "application/json", token)),
                print_dry_run);
  }
  if (command == "query" && (words.size() == 2 || words.size() == 4)) {
    json body = {{"goal", words[1]}};
    if (words.size() == 4) {
      if (words[2] != "--max") throw UsageError("query GOAL [--max N]");
      body["max_solutions"] = parse_count(words[3]);
    }
    return emit(parse_answer(client.request("POST", "/api/v1/query", body.dump())), print_query);
  }
  if (command == "replay" && words.size() >= 2) return replay(client, token, words, raw_json);
  if (command == "grid" && words.size() == 2 && words[1] == "extract") {
    return emit(parse_answer(client.request("POST", "/api/v1/grid/extract", "{}", "application/json", token)),
                [](const json& r) {
                  if (r["observation"].is_null()) {
                    std::cout << "no lines in the grid\n";
                    return;
                  }
                  std::cout << r["segments"] << " grid lines, observation " << r["observation"] << "\n";
                  for (const auto& d : r["decisions"]) print_decision(d);
                });
  }
  if (command == "grid") {
    std::string out, layer = "bayes", bbox;
    for_each_option(words, 1, "grid --out FILE.pgm [--layer L] [--bbox x0,y0,x1,y1]", "grid takes --out, --layer, --bbox",
                    [&](const std::string& flag, const std::string& value) {
      if (flag == "--out") out = value;
      else if (flag == "--layer") layer = value;
      else if (flag == "--bbox") bbox = value;
      else return false;
      return true;
    });
    if (out.empty()) throw UsageError("grid needs --out FILE.pgm");
    const std::string query = "?layer=" + layer + (bbox.empty() ? "" : "&bbox=" + bbox);
    const auto image = client.request("GET", "/api/v1/grid" + query + "&format=pgm");
    if (image.status != 200) parse_answer(image);
    write_file(out, image.body);
    std::cout << "wrote " << out << " (" << image.body.size() << " bytes)\n";
    if (layer == "bayes") {
      // map_server reads the image path relative to the YAML file.
      const auto yaml = client.request("GET", "/api/v1/grid/map.yaml" + (bbox.empty() ? std::string() : "?bbox=" + bbox));
      if (yaml.status != 200) parse_answer(yaml);
      std::string text = yaml.body;
      const auto at = text.find("image: map.pgm");
      if (at != std::string::npos) text.replace(at, 14, "image: " + std::filesystem::path(out).filename().string());
      const auto yaml_path = std::filesystem::path(out).replace_extension(".yaml").string();
      write_file(yaml_path, text);
      std::cout << "wrote " << yaml_path << "\n";
    }
    return kExitOk;
  }
  throw UsageError("unknown command '" + command + "'");
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const UsageError& e) {
    std::cerr << "wmctl: " << e.what() << "\n" << kUsage;
    return kExitUsage;
  } catch (const wm::client::ConnectionError& e) {
    std::cerr << "wmctl: " << e.what() << "\n";
    return kExitUnreachable;
  } catch (const ServerError& e) {
    std::cerr << "wmctl: " << e.what() << "\n";
    return kExitServerError;
  } catch (const std::exception& e) {
    std::cerr << "wmctl: " << e.what() << "\n";
    return kExitServerError;
  }
}
