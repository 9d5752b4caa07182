// wmctl: the command-line client of wmd, over the HTTP/JSON API only.
//
// Every command is a row of command_table(): dispatch, `wmctl help`, `wmctl help COMMAND` and the usage printed
// with an error all come from it, so a flag a command takes is always in its usage.
#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "clients/wmctl/commands.h"

namespace wm::wmctl {
namespace {

const char* kGlobalUsage = "usage: wmctl [--server URL] [--map ID] [--token TOKEN] [--json] COMMAND [ARGUMENTS]\n";
const char* kGlobalOptions =
    "options:\n"
    "  --server URL   default http://127.0.0.1:8080 (or $WMCTL_SERVER)\n"
    "  --map ID       work on map ID (GET /api/v1/maps lists them; default: the default map, or $WMCTL_MAP)\n"
    "  --token TOKEN  sent with the requests that change the map or the rules\n"
    "  --json         print the server's JSON as it came (for scripts)\n"
    "  --help, -h     this text; `wmctl help COMMAND` for one command\n";

std::vector<Command> command_table() {
  return {
      {"health", {}, {}, "server status, counts and loaded rules", health},
      {"network", {}, {}, "the processing network: executors' load, functions' activations, queues", network},
      {"network subtask",
       {"NAME", "on|off"},
       {},
       "start (on) or stop (off) a subtask of the processing network while it runs",
       network_subtask},
      {"network set",
       {"COMPONENT", "KEY=VALUE..."},
       {},
       "change parameters of a component while the network runs (e.g. grid extract_every=20)",
       network_set},
      {"maps", {}, {}, "the server's maps: id, plan, elements, observations, robots", maps_list},
      {"cluster", {}, {}, "the cluster's nodes (alive, heartbeat, maps), every map's lease and epoch", cluster},
      {"maps create", {"ID"}, {}, "a new, empty map (1-32 of a-z, 0-9, '_', '-')", maps_create},
      {"maps delete", {"ID"}, {}, "delete a map and its file (not the default map)", maps_delete},
      {"maps import",
       {"BUILDING.yaml"},
       {{"--prefix", "ID", true}},
       "an Open-RMF building.yaml as one map per level, ID-<level>, each with its level's plan (all or nothing)",
       maps_import},
      {"floorplan load",
       {"FILE"},
       {{"--mapping", "M.json"}, {"--units", "m|cm|mm|in|ft"}, {"--level", "NAME"}},
       "load a floor plan: JSON, AMRL vector map, DXF, Open-RMF building.yaml\n"
       "(--mapping, --units and --level apply to DXF and RMF files)",
       floorplan_load},
      {"floorplan show", {}, {}, "print the loaded floor plan", floorplan_show},
      {"floorplan align",
       {},
       {{"--apply", ""},
        {"--apply-ambiguous", ""},
        {"--redecide", ""},
        {"--max-translation", "M"},
        {"--max-rotation", "DEG"},
        {"--scale", "S|A,B|units"},
        {"--min-score", "F"},
        {"--time-budget", "MS"}},
       "search where the plan sits on the robots' grid (default +-10 m, +-180 deg, scale 1);\n"
       "prints the best placement, its score and the runner-up; --apply puts it in force\n"
       "when it is sound (--apply-ambiguous: even when ambiguous), --redecide then re-decides\n"
       "the observed elements against it",
       floorplan_align},
      {"floorplan place",
       {"X", "Y", "THETA_DEG"},
       {{"--scale", "S"}},
       "put the plan's frame at (X, Y) [m], turned by THETA_DEG, optionally scaled",
       floorplan_place},
      {"floorplan pairs",
       {"FILE"},
       {{"--scale", ""}, {"--preview", ""}},
       "place the plan from point pairs: FILE has lines 'plan_x plan_y world_x world_y'\n"
       "(two or more; # comments); --scale fits the scale too; --preview applies nothing",
       floorplan_pairs},
      {"floorplan undo", {}, {}, "go back to the placement before the one in force", floorplan_undo},
      {"floorplan redecide",
       {},
       {},
       "re-decide every observed element against the plan as placed now",
       floorplan_redecide},
      {"floorplan georeference",
       {},
       {{"--lat", "DEG"}, {"--lon", "DEG"}, {"--heading", "DEG"}, {"--clear", ""}},
       "set the world origin's WGS 84 latitude/longitude and the bearing of its x axis\n"
       "(GeoJSON exports are then longitude/latitude), or --clear it",
       floorplan_georeference},
      {"primitives post",
       {"FILE"},
       {},
       "post line primitives (JSON, as POST /api/v1/primitives), print decisions",
       primitives_post},
      {"map",
       {},
       {{"--format", "dxf|geojson"}, {"--out", "FILE"}, {"--bbox", "X0,Y0,X1,Y1"}},
       "objects and observed elements; with --format and --out, export them to FILE;\n"
       "with --bbox, only what crosses that box (metres)",
       map},
      {"map quality",
       {},
       {},
       "how good the vector map is against the Bayes grid: precision, recall,\n"
       "redundancy, calibration of the elements' covariances",
       map_quality},
      {"report", {}, {}, "as-built report: what was confirmed, moved, missing, gone, never observed", report},
      {"changes",
       {},
       {},
       "the differences between plan and building (walls missing, objects moved or gone,\n"
       "new walls), each with its evidence and confidence",
       changes},
      {"changes accept",
       {"ID"},
       {},
       "accept a listed change into the plan (a new plan version; token)",
       changes_accept},
      {"changes reject", {"ID"}, {}, "reject a listed change: it is no longer listed (token)", changes_reject},
      {"changes undo", {}, {}, "undo the last accept or reject (token)", changes_undo},
      {"decisions", {}, {{"--since", "SEQ"}, {"--limit", "N"}, {"--element", "ID"}}, "the decision log", decisions},
      {"explain", {"ID"}, {}, "history of an element or object: observations, rules, numbers", explain},
      {"rules", {}, {}, "loaded rule files, checksums, last reload error", rules},
      {"rules reload", {}, {}, "reload the rules directory now (atomic; needs the token if set)", rules_reload},
      {"rules dry-run",
       {"FILE"},
       {{"--last", "N"}},
       "re-decide the last N decisions with FILE in place of its namesake",
       rules_dry_run},
      {"query", {"GOAL"}, {{"--max", "N"}}, "read-only Prolog query against the knowledge base", query},
      {"replay",
       {"LOG"},
       {{"--limit", "N"},
        {"--every", "K"},
        {"--rate", "HZ"},
        {"--offset", "DX,DY"},
        {"--source", "NAME"},
        {"--range-max", "M"},
        {"--usable-range", "M"},
        {"--pose-sigma", "XY,THETA"}},
       "post the laser scans of a CARMEN log (FLASER / ROBOTLASER1, plain or .gz)\n"
       "in line order, with a progress bar and a summary",
       replay},
      {"grid",
       {},
       {{"--out", "FILE.pgm", true}, {"--layer", "L"}, {"--bbox", "x0,y0,x1,y1"}},
       "save a grid layer (bayes, ds_belief, ds_plausibility, ds_conflict) as PGM;\n"
       "with the bayes layer also FILE.yaml for ROS map_server",
       grid},
      {"grid extract", {}, {}, "run the grid line extractor now; its lines are decided like primitives", grid_extract},
      {"robots", {}, {}, "the robots heard from: status, pose, what they sent", robots},
      {"shm",
       {},
       {{"--tiles", "N"}},
       "check the shared-memory export on this machine: open the segment GET /api/v1/shm names,\n"
       "read every tile, compare N of them (default 64) bit for bit with GET /api/v1/grid/tiles",
       shm_check},
  };
}

// The command's usage line and its summary, indented.
std::string describe(const Command& command) {
  std::string text = "  " + usage_line(command) + "\n";
  std::string_view summary = command.summary;
  while (!summary.empty()) {
    const auto end = std::min(summary.find('\n'), summary.size());
    text += "      " + std::string(summary.substr(0, end)) + "\n";
    summary.remove_prefix(std::min(end + 1, summary.size()));
  }
  return text;
}

std::string full_usage(const std::vector<Command>& table) {
  std::string text = std::string(kGlobalUsage) + "commands:\n";
  for (const auto& command : table) text += describe(command);
  return text + kGlobalOptions;
}

std::string command_usage(const Command& command) {
  return "usage: wmctl [--server URL] [--map ID] [--token TOKEN] [--json] " + usage_line(command) + "\n";
}

// How many leading words of `words` name `command`; 0 when they do not.
std::size_t match(const Command& command, const std::vector<std::string>& words) {
  std::size_t matched = 0;
  std::string_view name = command.name;
  while (!name.empty()) {
    const auto end = std::min(name.find(' '), name.size());
    if (matched >= words.size() || words[matched] != name.substr(0, end)) return 0;
    ++matched;
    name.remove_prefix(std::min(end + 1, name.size()));
  }
  return matched;
}

// The command whose name matches the most leading words ("grid extract" before "grid"), or nullptr.
const Command* find_command(const std::vector<Command>& table, const std::vector<std::string>& words,
                            std::size_t& name_words) {
  const Command* best = nullptr;
  name_words = 0;
  for (const auto& command : table) {
    const auto n = match(command, words);
    if (n > name_words) best = &command, name_words = n;
  }
  return best;
}

// `wmctl help [COMMAND...]`: the whole list, or the commands that start with the words given.
int help(const std::vector<Command>& table, const std::vector<std::string>& words) {
  if (words.empty()) {
    std::cout << full_usage(table);
    return kExitOk;
  }
  std::string text;
  for (const auto& command : table)
    if (match(command, words) == words.size()) text += describe(command);
  if (text.empty()) throw UsageError("help: unknown command '" + words[0] + "'");
  std::cout << text;
  return kExitOk;
}

int run(const std::vector<std::string>& args, const std::vector<Command>& table) {
  std::string server = std::getenv("WMCTL_SERVER") ? std::getenv("WMCTL_SERVER") : "http://127.0.0.1:8080";
  std::string token;
  std::string map = std::getenv("WMCTL_MAP") ? std::getenv("WMCTL_MAP") : "";
  bool raw_json = false;
  std::vector<std::string> words;
  for (std::size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--server" || args[i] == "--token" || args[i] == "--map") {
      if (i + 1 >= args.size()) throw UsageError(args[i] + " needs a value");
      std::string& target = args[i] == "--server" ? server : args[i] == "--token" ? token : map;
      target = args[++i];
    } else if (args[i] == "--json") {
      raw_json = true;
    } else if (args[i] == "--help" || args[i] == "-h") {
      std::cout << full_usage(table);
      return kExitOk;
    } else {
      words.push_back(args[i]);
    }
  }
  if (words.empty()) throw UsageError("no command");
  if (words[0] == "help") return help(table, {words.begin() + 1, words.end()});
  std::size_t name_words = 0;
  const Command* command = find_command(table, words, name_words);
  if (command == nullptr) {
    std::string family;  // "floorplan" alone: name its subcommands
    for (const auto& c : table)
      if (c.name.starts_with(words[0] + " ")) family += (family.empty() ? "" : ", ") + std::string(c.name);
    if (!family.empty()) throw UsageError("'" + words[0] + "' needs a subcommand: " + family);
    throw UsageError("unknown command '" + words[0] + "'");
  }
  // The server judges the id; only what would change the path is refused here.
  if (map.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_-") != std::string::npos)
    throw UsageError("--map: a map id is made of a-z, 0-9, '_' and '-'");
  client::HttpClient client(server);
  client.use_map(map);
  Invocation invocation{client, token, raw_json, {}, {}};
  try {
    parse_arguments(*command, {words.begin() + static_cast<std::ptrdiff_t>(name_words), words.end()}, invocation);
    return command->run(invocation);
  } catch (UsageError& e) {
    if (e.usage.empty()) e.usage = command_usage(*command);
    throw;
  }
}

}  // namespace
}  // namespace wm::wmctl

int main(int argc, char** argv) {
  using namespace wm::wmctl;
  const auto table = command_table();
  try {
    return run(std::vector<std::string>(argv + 1, argv + argc), table);
  } catch (const UsageError& e) {
    std::cerr << "wmctl: " << e.what() << "\n" << (e.usage.empty() ? full_usage(table) : e.usage);
    return kExitUsage;
  } catch (const wm::client::ConnectionError& e) {
    std::cerr << "wmctl: " << e.what() << "\n";
    return kExitUnreachable;
  } catch (const std::exception& e) {  // ServerError and anything else: the server's or the log's reason
    std::cerr << "wmctl: " << e.what() << "\n";
    return kExitServerError;
  }
}
