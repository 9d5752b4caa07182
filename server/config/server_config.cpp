#include "server/config/server_config.h"

#include <charconv>
#include <chrono>
#include <cmath>
#include <fstream>
#include <sstream>

namespace wm::config {
namespace {

template <typename T>
T parse_number(const std::string& flag, const std::string& text, T min, T max) {
  T value{};
  auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || p != text.data() + text.size() || !(value >= min && value <= max))
    throw ConfigError(flag + ": expected a number in [" + std::to_string(min) + ", " + std::to_string(max) + "], got '" + text + "'");
  return value;
}

}  // namespace

std::string usage() {
  return "usage: wmd [options]\n"
         "  --db FILE              SQLite file of the world model (default worldmodel.db; created if missing)\n"
         "  --port N               TCP port (default 8080; 0 picks a free one, printed at start)\n"
         "  --bind ADDR            address to listen on (default 127.0.0.1)\n"
         "  --rules DIR            directory of *.pl rule files (default: the shipped rules/prolog)\n"
         "  --floorplan FILE       load this JSON floor plan at start (replaces the stored one)\n"
         "  --token TOKEN          require 'Authorization: Bearer TOKEN' for requests that change state\n"
         "  --max-body-bytes N     largest accepted request body (default 16777216)\n"
         "  --threads N            HTTP I/O threads (default 4)\n"
         "  --gate-chi2 X          χ² gate (2 dof) for matching segments (default 5.991, 95 %)\n"
         "  --max-gap M            largest gap [m] between collinear extents still matched (default 0.10)\n"
         "  --grid-resolution M    occupancy grid cell size [m] (default 0.05; a stored grid keeps its own)\n"
         "  --grid-flush-ms N      write changed grid tiles at most every N ms (default 1000; scans are journaled at once)\n"
         "  --grid-extract-every N run the grid line extractor every N scans (default 0: POST /api/v1/grid/extract)\n"
         "  --no-scan-lines        laser scans update the grids only, without the scan line extractor\n"
         "  --layer-mapping FILE   DXF layer/block mapping (JSON) for uploads that bring none (default: built in)\n"
         "  --web DIR              the web viewer's files (default: the shipped clients/web; '' disables)\n"
         "  --no-watch-rules       do not reload the rules when their files change (POST /api/v1/rules/reload still does)\n"
         "  --rule-inferences N    inference limit per decision and query (default 200000)\n"
         "  --rule-time-limit S    time limit per decision and query [s] (default 1)\n"
         "  --sync normal|full     SQLite synchronous mode (default full: durable across power loss)\n"
         "  --help                 this text\n";
}

ServerConfig parse_command_line(const std::vector<std::string>& args, const std::filesystem::path& default_rules_dir,
                                const std::filesystem::path& default_web_dir) {
  ServerConfig c;
  c.api.web_dir = default_web_dir.string();
  c.rules.rules_dir = default_rules_dir;
  bool watch_rules = true;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& flag = args[i];
    if (flag == "--help" || flag == "-h") {
      c.help = true;
      continue;
    }
    if (flag == "--no-watch-rules") {
      watch_rules = false;
      continue;
    }
    if (flag == "--no-scan-lines") {
      c.service.extract_scan_lines = false;
      continue;
    }
    if (i + 1 >= args.size()) throw ConfigError(flag.rfind("--", 0) == 0 ? flag + ": missing value" : "unexpected argument '" + flag + "'");
    const std::string& value = args[++i];
    if (flag == "--db") c.store.path = value;
    else if (flag == "--port") c.http.port = parse_number<unsigned short>(flag, value, 0, 65535);
    else if (flag == "--bind") c.http.bind_address = value;
    else if (flag == "--rules") c.rules.rules_dir = value;
    else if (flag == "--floorplan") c.floor_plan_file = value;
    else if (flag == "--web") c.api.web_dir = value;
    else if (flag == "--layer-mapping") {
      std::ifstream in(value);
      if (!in) throw ConfigError("--layer-mapping: cannot read '" + value + "'");
      std::ostringstream text;
      text << in.rdbuf();
      try {
        c.api.layer_mapping = apriori::parse_layer_mapping_json(text.str());
      } catch (const std::exception& e) {
        throw ConfigError("--layer-mapping: " + std::string(e.what()));
      }
    }
    else if (flag == "--token") c.api.token = value;
    else if (flag == "--max-body-bytes") c.http.max_body_bytes = parse_number<std::size_t>(flag, value, 1024, std::size_t{1} << 31);
    else if (flag == "--threads") c.http.threads = parse_number<int>(flag, value, 1, 64);
    else if (flag == "--gate-chi2") c.service.world.match.gate_chi2 = parse_number<double>(flag, value, 0.01, 1e4);
    else if (flag == "--max-gap") c.service.world.match.max_gap_m = parse_number<double>(flag, value, 0.0, 100.0);
    else if (flag == "--rule-inferences") c.rules.inference_limit = parse_number<std::int64_t>(flag, value, 1000, 1'000'000'000);
    else if (flag == "--rule-time-limit") c.rules.time_limit_s = parse_number<double>(flag, value, 0.001, 60.0);
    else if (flag == "--grid-flush-ms")
      c.service.grid_flush_interval = std::chrono::milliseconds(parse_number<std::int64_t>(flag, value, 0, 86'400'000));
    else if (flag == "--grid-extract-every")
      c.service.grid_extract_every = parse_number<std::size_t>(flag, value, 0, 1'000'000);
    else if (flag == "--grid-resolution") c.service.grid.resolution_m = parse_number<double>(flag, value, 0.005, 10.0);
    else if (flag == "--sync") {
      if (value != "full" && value != "normal") throw ConfigError("--sync: expected 'full' or 'normal'");
      c.store.synchronous_full = value == "full";
    } else {
      throw ConfigError("unknown option '" + flag + "'");
    }
  }
  if (c.store.path.empty()) throw ConfigError("--db: must not be empty");
  if (!std::filesystem::is_directory(c.rules.rules_dir))
    throw ConfigError("--rules: '" + c.rules.rules_dir.string() + "' is not a directory");
  if (watch_rules) c.service.watch_rules_dir = c.rules.rules_dir;
  if (c.floor_plan_file && !std::filesystem::is_regular_file(*c.floor_plan_file))
    throw ConfigError("--floorplan: cannot read '" + c.floor_plan_file->string() + "'");
  return c;
}

}  // namespace wm::config
