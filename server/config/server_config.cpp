#include "server/config/server_config.h"

#include <unistd.h>

#include <algorithm>
#include <boost/asio/ip/address.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <regex>
#include <sstream>

#include "common/parse_number.h"
#include "server/http/forward_client.h"
#include "server/storage/postgres.h"

namespace wm::config {
namespace {

// A numeric flag's value (wm::parse_number), its error as a ConfigError.
template <typename T>
T config_number(const std::string& flag, const std::string& text, T min, T max) {
  try {
    return parse_number<T>(flag, text, min, max);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(e.what());
  }
}

// "a, B,c" → {"a", "b", "c"}: lower case (host names and origins compare without case), no empty items.
std::vector<std::string> comma_list(const std::string& text) {
  std::vector<std::string> items;
  std::string current;
  for (const char ch : text + ",") {
    if (ch == ',') {
      if (!current.empty()) items.push_back(current);
      current.clear();
    } else if (ch != ' ') {
      current.push_back(ch >= 'A' && ch <= 'Z' ? static_cast<char>(ch - 'A' + 'a') : ch);
    }
  }
  return items;
}

// Whether a postgresql:// URI names a password: user:password@ before the host, or a password= parameter.
bool uri_has_password(std::string_view uri) {
  const auto scheme = uri.find("://");
  const auto rest = uri.substr(scheme == std::string_view::npos ? 0 : scheme + 3);
  const auto at = rest.find('@');
  const auto slash = rest.find('/');
  if (at != std::string_view::npos && (slash == std::string_view::npos || at < slash) &&
      rest.substr(0, at).find(':') != std::string_view::npos)
    return true;
  const auto query = uri.find('?');
  if (query == std::string_view::npos) return false;
  const auto parameters = "&" + std::string(uri.substr(query + 1));
  return parameters.find("&password=") != std::string::npos;
}

}  // namespace

std::string usage() {
  return "usage: wmd [options]\n"
         "  --db FILE              SQLite file of the world model (default worldmodel.db; created if missing)\n"
         "  --store URI            the world model in PostgreSQL (postgresql://user@host:port/database) instead of\n"
         "                         a SQLite file; the password from PGPASSWORD or a password file (PGPASSFILE,\n"
         "                         ~/.pgpass), never on the command line\n"
         "  --store-schema NAME    the PostgreSQL schema that holds the map (default worldmodel; created if missing)\n"
         "  --node-id ID           this wmd's name on the leases of the maps it writes in PostgreSQL (default: host\n"
         "                         name and process id); one node writes a map at a time\n"
         "  --lease-ttl-ms N       a map's lease runs N ms unless renewed (every N/3; default 3000)\n"
         "  --cluster-id ID        join the cluster ID of wmd nodes sharing the --store database: each map of\n"
         "                         /api/v1/maps is served by one node, any node answers for it, a dead node's maps\n"
         "                         are taken over; the node-to-node token from --cluster-token-file or the\n"
         "                         environment (WM_CLUSTER_TOKEN); the node's own default map in schema\n"
         "                         node_<node id> unless --store-schema\n"
         "  --cluster-token-file F the node-to-node token (at least 16 characters), shared by the cluster's nodes\n"
         "  --advertise URL        where the other nodes reach this one (default http://<bind address>:<port>)\n"
         "  --maps-dir DIR         the other maps (POST /api/v1/maps), one SQLite file each (default: the --db file's\n"
         "                         name + '.maps', beside it; made when the first map is)\n"
         "  --port N               TCP port (default 8080; 0 picks a free one, printed at start)\n"
         "  --bind ADDR            address to listen on (default 127.0.0.1)\n"
         "  --rules DIR            directory of *.pl rule files (default: the shipped rules/prolog)\n"
         "  --floorplan FILE       load this JSON floor plan at start (replaces the stored one)\n"
         "  --token TOKEN          require 'Authorization: Bearer TOKEN' for requests that change state, dry runs\n"
         "                         and the events WebSocket (which also takes ?token=TOKEN)\n"
         "  --insecure-no-token    allow a non-loopback --bind without --token (anyone who reaches the port can "
         "write)\n"
         "  --allow-dry-run-without-token  allow POST /api/v1/rules/dry-run when no --token is set (default: 403)\n"
         "  --allowed-hosts LIST   comma-separated host names accepted in the Host header besides localhost,\n"
         "                         127.0.0.1, [::1] and the bind address (IP addresses always pass; '*': no check)\n"
         "  --allowed-origins LIST comma-separated origins (http://host:port) whose pages may use the events\n"
         "                         WebSocket and send writes, besides the server's own\n"
         "  --max-body-bytes N     largest accepted request body (default 16777216)\n"
         "  --threads N            HTTP I/O threads (default 4)\n"
         "  --handler-threads N    threads that run read handlers off the I/O threads (default 8)\n"
         "  --write-threads N      threads that wait for writes to be applied (default 32: one per robot posting at\n"
         "                         once, so the store can commit them together)\n"
         "  --handler-queue N      requests waiting for a handler thread before 503 + Retry-After (default 256)\n"
         "  --gate-sigmas N        a segment matches within N σ in direction and offset (default 3)\n"
         "  --max-gap M            largest gap [m] between collinear extents still matched (default 0.10)\n"
         "  --grid-resolution M    occupancy grid cell size [m] (default 0.05; a stored grid keeps its own)\n"
         "  --usable-range M       returns beyond M only clear space, for scans that give no usable_range (default "
         "20)\n"
         "  --sonar-gate on|off    judge sonar readings by the laser before they reach the fused grid (default on)\n"
         "  --ds-decision B,P,K    the DS decision layer: occupied at belief >= B, free at plausibility <= P, "
         "conflict\n"
         "                         at K >= K (default 0.6,0.4,0.6)\n"
         "  --grid-flush-ms N      write changed grid tiles at most every N ms (default 1000; scans are journaled at "
         "once)\n"
         "  --grid-extract-every N run the grid line extractor every N scans (default 0: POST /api/v1/grid/extract)\n"
         "  --network FILE         run the ingest on this processing network (YAML task file; default: the built-in\n"
         "                         network, printed by --print-network)\n"
         "  --print-network        print the default network's task file and exit\n"
         "  --grid-trim-every N    every N scans, cut elements' ends back to what the Bayes grid backs and let the "
         "rules\n"
         "                         prune what it backs nowhere (default 10; 0: never)\n"
         "  --no-scan-lines        laser scans update the grids only, without the scan line extractor\n"
         "  --no-scan-alignment    laser scans keep the posted pose (not aligned to the map's lines first)\n"
         "  --layer-mapping FILE   DXF layer/block mapping (JSON) for uploads that bring none (default: built in)\n"
         "  --web DIR              the web viewer's files (default: the shipped clients/web; '' disables)\n"
         "  --no-watch-rules       do not reload the rules when their files change (POST /api/v1/rules/reload still "
         "does)\n"
         "  --rule-inferences N    inference limit per decision and query (default 200000)\n"
         "  --rule-time-limit S    time limit per decision and query [s] (default 1)\n"
         "  --sync normal|full     SQLite synchronous mode (default full: durable across power loss)\n"
         "  --no-shm               do not export the grid and the map to shared memory (GET /api/v1/shm)\n"
         "  --shm-max-mb N         largest shared memory segment [MB] (default 1024; never more than half of\n"
         "                         /dev/shm's free space)\n"
         "  --shm-period-ms N      copy changes into shared memory at most every N ms (default 20)\n"
         "  --foxglove-queue-kb N  changes (scene updates, decisions) a Foxglove client may have queued [KiB]; past\n"
         "                         them it falls behind and is sent the current state when it reads (default 32768)\n"
         "  --foxglove-max-clients N  Foxglove clients served at once; one more is refused (default 32)\n"
         "  --drive-max-speed M/S  drivers' commands are clamped to this linear speed (default 0.4)\n"
         "  --drive-max-turn RAD/S drivers' commands are clamped to this turn rate (default 1.25)\n"
         "  --drive-hold-ms N      stop a robot whose driver sent nothing for N ms (default 150)\n"
         "  --help                 this text\n";
}

ServerConfig parse_command_line(const std::vector<std::string>& args, const std::filesystem::path& default_rules_dir,
                                const std::filesystem::path& default_web_dir) {
  ServerConfig c;
  c.api.web_dir = default_web_dir.string();
  c.rules.rules_dir = default_rules_dir;
  bool watch_rules = true;
  bool insecure_no_token = false;
  bool schema_given = false;
  std::optional<std::string> token_file;
  std::vector<std::string> extra_hosts;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& flag = args[i];
    if (flag == "--help" || flag == "-h") {
      c.help = true;
      continue;
    }
    if (flag == "--print-network") {
      c.print_network = true;
      continue;
    }
    if (flag == "--no-watch-rules") {
      watch_rules = false;
      continue;
    }
    if (flag == "--no-scan-lines") {
      c.service.ingest.extract_scan_lines = false;
      continue;
    }
    if (flag == "--no-scan-alignment") {
      c.service.ingest.align_scans = false;
      continue;
    }
    if (flag == "--no-shm") {
      c.shm.enabled = false;
      continue;
    }
    if (flag == "--insecure-no-token") {
      insecure_no_token = true;
      continue;
    }
    if (flag == "--allow-dry-run-without-token") {
      c.api.allow_dry_run_without_token = true;
      continue;
    }
    if (i + 1 >= args.size())
      throw ConfigError(flag.rfind("--", 0) == 0 ? flag + ": missing value" : "unexpected argument '" + flag + "'");
    const std::string& value = args[++i];
    if (flag == "--db" || flag == "--store")
      c.store.path = value;
    else if (flag == "--store-schema") {
      c.store.postgres_schema = value;
      schema_given = true;
    } else if (flag == "--cluster-id")
      c.cluster_id = value;
    else if (flag == "--cluster-token-file")
      token_file = value;
    else if (flag == "--advertise")
      c.advertise_url = value;
    else if (flag == "--node-id")
      c.node_id = value;
    else if (flag == "--lease-ttl-ms")
      c.lease_ttl = std::chrono::milliseconds(config_number<std::int64_t>(flag, value, 300, 600'000));
    else if (flag == "--maps-dir")
      c.maps_dir = value;
    else if (flag == "--port")
      c.http.port = config_number<unsigned short>(flag, value, 0, 65535);
    else if (flag == "--bind")
      c.http.bind_address = value;
    else if (flag == "--rules")
      c.rules.rules_dir = value;
    else if (flag == "--floorplan")
      c.floor_plan_file = value;
    else if (flag == "--web")
      c.api.web_dir = value;
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
    } else if (flag == "--token")
      c.api.token = value;
    else if (flag == "--max-body-bytes")
      c.http.max_body_bytes = config_number<std::size_t>(flag, value, 1024, std::size_t{1} << 31);
    else if (flag == "--threads")
      c.http.threads = config_number<int>(flag, value, 1, 64);
    else if (flag == "--handler-threads")
      c.http.handler_threads = config_number<int>(flag, value, 1, 256);
    else if (flag == "--handler-queue")
      c.http.handler_queue = config_number<std::size_t>(flag, value, 1, 100000);
    else if (flag == "--allowed-hosts") {
      for (auto& host : comma_list(value)) {
        if (host.find('/') != std::string::npos)
          throw ConfigError("--allowed-hosts: '" + host + "' is not a host name");
        if (host.front() != '[') host = host.substr(0, host.find(':'));  // a port, if given, is not compared
        extra_hosts.push_back(std::move(host));
      }
    } else if (flag == "--allowed-origins") {
      for (auto& origin : comma_list(value)) {
        while (!origin.empty() && origin.back() == '/') origin.pop_back();
        if (origin.rfind("http://", 0) != 0 && origin.rfind("https://", 0) != 0)
          throw ConfigError("--allowed-origins: '" + origin + "' is not an origin like http://host:port");
        c.api.allowed_origins.push_back(std::move(origin));
      }
    } else if (flag == "--gate-chi2")
      throw ConfigError("--gate-chi2: matching no longer uses a χ² gate on (ρ, φ); use --gate-sigmas N");
    else if (flag == "--gate-sigmas")
      c.service.map.world.match.gate_sigmas = config_number<double>(flag, value, 0.5, 10.0);
    else if (flag == "--max-gap")
      c.service.map.world.match.max_gap_m = config_number<double>(flag, value, 0.0, 100.0);
    else if (flag == "--rule-inferences")
      c.rules.inference_limit = config_number<std::int64_t>(flag, value, 1000, 1'000'000'000);
    else if (flag == "--rule-time-limit")
      c.rules.time_limit_s = config_number<double>(flag, value, 0.001, 60.0);
    else if (flag == "--grid-flush-ms")
      c.service.grids.flush_interval =
          std::chrono::milliseconds(config_number<std::int64_t>(flag, value, 0, 86'400'000));
    else if (flag == "--network")
      c.service.ingest.network_file = std::filesystem::path(value);
    else if (flag == "--write-threads")
      c.http.write_threads = config_number<int>(flag, value, 1, 1024);
    else if (flag == "--grid-extract-every")
      c.service.ingest.grid_extract_every = config_number<std::size_t>(flag, value, 0, 1'000'000);
    else if (flag == "--grid-trim-every")
      c.service.ingest.grid_trim_every = config_number<std::size_t>(flag, value, 0, 1'000'000);
    else if (flag == "--grid-resolution")
      c.service.grids.grid.resolution_m = config_number<double>(flag, value, 0.005, 10.0);
    else if (flag == "--sonar-gate") {
      if (value != "on" && value != "off") throw ConfigError("--sonar-gate: expected 'on' or 'off'");
      c.service.grids.laser_sonar.gate_sonar = value == "on";
    } else if (flag == "--ds-decision") {
      const auto parts = comma_list(value);
      if (parts.size() != 3) throw ConfigError("--ds-decision: expected B,P,K (three numbers)");
      auto& decision = c.service.grids.laser_sonar.decision;
      decision.occupied_belief_min = config_number<double>(flag, parts[0], 0.01, 1.0);
      decision.free_plausibility_max = config_number<double>(flag, parts[1], 0.0, 0.99);
      decision.conflict_min = config_number<double>(flag, parts[2], 0.01, 2.0);
    } else if (flag == "--usable-range")
      c.service.grids.grid.sensor.max_usable_range_m = config_number<double>(flag, value, 0.1, 1000.0);
    else if (flag == "--shm-max-mb")
      c.shm.max_bytes = config_number<std::uint64_t>(flag, value, 1, 1'048'576) << 20;
    else if (flag == "--shm-period-ms")
      c.shm.period = std::chrono::milliseconds(config_number<std::int64_t>(flag, value, 1, 10'000));
    else if (flag == "--foxglove-queue-kb")
      c.foxglove.max_queued_bytes = config_number<std::size_t>(flag, value, 16, 4'194'304) << 10;
    else if (flag == "--foxglove-max-clients")
      c.foxglove.max_clients = config_number<std::size_t>(flag, value, 1, 4096);
    else if (flag == "--drive-max-speed")
      c.drive.max_linear_mps = config_number<double>(flag, value, 0.01, 5.0);
    else if (flag == "--drive-max-turn")
      c.drive.max_angular_radps = config_number<double>(flag, value, 0.01, 10.0);
    else if (flag == "--drive-hold-ms")
      c.drive.hold_ms = config_number<int>(flag, value, 20, 5000);
    else if (flag == "--sync") {
      if (value != "full" && value != "normal") throw ConfigError("--sync: expected 'full' or 'normal'");
      c.store.synchronous_full = value == "full";
    } else {
      throw ConfigError("unknown option '" + flag + "'");
    }
  }
  if (c.store.path.empty()) throw ConfigError("--db: must not be empty");
  if (storage::is_postgres_uri(c.store.path) && uri_has_password(c.store.path))
    throw ConfigError(
        "--store: the URI carries a password, which other users can read on the command line; give it "
        "in PGPASSWORD or a password file (PGPASSFILE, ~/.pgpass)");
  if (c.node_id.empty()) {
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    c.node_id = std::string(host) + "-" + std::to_string(::getpid());
  }
  if (c.node_id.size() > 128 || std::any_of(c.node_id.begin(), c.node_id.end(), [](char ch) {
        return static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f;
      }))
    throw ConfigError("--node-id: at most 128 characters, no control characters");
  if (!c.cluster_id.empty() || token_file || !c.advertise_url.empty()) {
    if (c.cluster_id.empty()) throw ConfigError("--cluster-token-file and --advertise go with --cluster-id");
    if (!storage::is_postgres_uri(c.store.path))
      throw ConfigError("--cluster-id: a cluster's nodes share a PostgreSQL database: give --store postgresql://…");
    static const std::regex cluster_name("[A-Za-z0-9_.-]{1,64}");
    if (!std::regex_match(c.cluster_id, cluster_name)) throw ConfigError("--cluster-id: 1-64 of [A-Za-z0-9_.-]");
    if (token_file) {
      std::ifstream in(*token_file, std::ios::binary);
      if (!in) throw ConfigError("--cluster-token-file: cannot read '" + *token_file + "'");
      std::getline(in, c.cluster_token);
      while (!c.cluster_token.empty() && (c.cluster_token.back() == '\r' || c.cluster_token.back() == ' '))
        c.cluster_token.pop_back();
    } else if (const char* env = std::getenv("WM_CLUSTER_TOKEN")) {
      c.cluster_token = env;
    }
    if (c.cluster_token.size() < 16)
      throw ConfigError(
          "--cluster-id: the nodes pass each other requests with a shared token of at least 16 characters: put it "
          "in a file (--cluster-token-file) or WM_CLUSTER_TOKEN, never on the command line");
    if (!c.advertise_url.empty() && !http::parse_node_url(c.advertise_url))
      throw ConfigError("--advertise: expected http://HOST:PORT, got '" + c.advertise_url + "'");
    if (!schema_given) {
      // Each node's default map is its own: the cluster's maps are those of /api/v1/maps.
      c.store.postgres_schema = "node_";
      for (const char ch : c.node_id) {
        const char lower = ch >= 'A' && ch <= 'Z' ? static_cast<char>(ch - 'A' + 'a') : ch;
        c.store.postgres_schema +=
            (lower >= 'a' && lower <= 'z') || (lower >= '0' && lower <= '9') || lower == '-' ? lower : '_';
      }
      if (c.store.postgres_schema.size() > 63) {
        // Cut, with a hash of the whole id after it (FNV-1a: the same on every build, so a node finds its schema
        // again): two long ids that share their first characters stay apart.
        std::uint64_t hash = 14695981039346656037ull;
        for (const char ch : c.node_id) hash = (hash ^ static_cast<unsigned char>(ch)) * 1099511628211ull;
        char hex[17];
        std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash));
        c.store.postgres_schema = c.store.postgres_schema.substr(0, 46) + "_" + hex;
      }
    }
  }
  if (!storage::is_valid_schema_name(c.store.postgres_schema))
    throw ConfigError("--store-schema: '" + c.store.postgres_schema +
                      "' is not 1-63 of [a-z0-9_-] (a letter or '_' first)");
  if (c.maps_dir.empty()) c.maps_dir = c.store.path + ".maps";
  boost::system::error_code bad_address;
  const auto bind = boost::asio::ip::make_address(c.http.bind_address, bad_address);
  if (bad_address) throw ConfigError("--bind: '" + c.http.bind_address + "' is not an IP address");
  if (!bind.is_loopback() && c.api.token.empty() && !insecure_no_token)
    throw ConfigError("--bind " + c.http.bind_address +
                      " makes the server reachable from other machines, and without --token anyone who reaches the "
                      "port can change the map; give --token TOKEN (or --insecure-no-token on a trusted network)");
  // Host names requests may carry: loopback names, the bind address (IP literals pass anyway) and --allowed-hosts.
  const bool no_host_check = std::find(extra_hosts.begin(), extra_hosts.end(), "*") != extra_hosts.end();
  if (!no_host_check) {
    c.api.allowed_hosts = {"localhost", "127.0.0.1", "[::1]"};
    c.api.allowed_hosts.push_back(bind.is_v6() ? "[" + bind.to_string() + "]" : bind.to_string());
    c.api.allowed_hosts.insert(c.api.allowed_hosts.end(), extra_hosts.begin(), extra_hosts.end());
  }
  if (!std::filesystem::is_directory(c.rules.rules_dir))
    throw ConfigError("--rules: '" + c.rules.rules_dir.string() + "' is not a directory");
  if (watch_rules) c.service.watch_rules_dir = c.rules.rules_dir;
  if (c.floor_plan_file && !std::filesystem::is_regular_file(*c.floor_plan_file))
    throw ConfigError("--floorplan: cannot read '" + c.floor_plan_file->string() + "'");
  return c;
}

}  // namespace wm::config
