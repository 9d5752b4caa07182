// wmctl commands about the map: health, floor plan, primitives, map, as-built report, grid.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <string>

#include "clients/wmctl/commands.h"

namespace wm::wmctl {
namespace {

std::string point(const json& p) { return "(" + fixed(p[0].get<double>()) + ", " + fixed(p[1].get<double>()) + ")"; }

void print_map(const json& m) {
  std::cout << "map version " << m["version"] << ", plan '" << m["plan"].get<std::string>()
            << "': " << m["objects"].size() << " objects, " << m["elements"].size() << " observed elements\n";
  for (const auto& o : m["objects"]) {
    std::string attributes;
    for (const auto& a : o["attributes"]) attributes += (attributes.empty() ? "" : ",") + a.get<std::string>();
    std::cout << "  object " << std::left << std::setw(14) << o["id"].get<std::string>() << std::setw(10)
              << o["kind"].get<std::string>() << " [" << attributes << "] pose (" << fixed(o["pose"]["x"].get<double>())
              << ", " << fixed(o["pose"]["y"].get<double>()) << ", " << fixed(o["pose"]["theta"].get<double>(), 4)
              << ") edges " << o["edges"].size() << ", confirmed " << o["confirmations"] << ", adjusted "
              << o["adjustments"] << "\n";
  }
  for (const auto& e : m["elements"])
    std::cout << "  element " << std::left << std::setw(8) << e["id"].get<std::string>() << point(e["p0"]) << " -> "
              << point(e["p1"]) << "  support " << e["support"] << ", origin " << e["origin"].get<std::string>()
              << "\n";
}

// Writes the answer's body to `path` (the body is not JSON: an image or a drawing).
void save(const client::HttpResult& answer, const std::string& path) {
  if (answer.status != 200) parse_answer(answer);
  write_file(path, answer.body);
}

}  // namespace

int health(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/health")), [](const json& h) {
    std::cout << "status " << h["status"].get<std::string>() << ", map version " << h["version"] << ", plan '"
              << h["plan"].get<std::string>() << "', " << h["objects"] << " objects, " << h["elements"]
              << " elements\n";
    for (const auto& f : h["rules"]["files"]) std::cout << "rules: " << f["path"].get<std::string>() << "\n";
    if (!h["rules"]["last_error"].get<std::string>().empty())
      std::cout << "last rules error: " << h["rules"]["last_error"].get<std::string>() << "\n";
  });
}

int maps_list(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/maps")), [](const json& answer) {
    for (const auto& m : answer["maps"]) {
      if (!m.contains("plan_name")) {  // a map another node of the cluster serves
        std::cout << m["id"].get<std::string>() << ": served by "
                  << (m["node"].is_string()
                          ? "node " + m["node"].get<std::string>() + " at " + m["owner"].get<std::string>()
                          : std::string("no node yet (being taken over)"))
                  << "\n";
        continue;
      }
      std::cout << m["id"].get<std::string>() << (m["default"].get<bool>() ? " (default)" : "") << ": plan '"
                << m["plan_name"].get<std::string>() << "', " << m["objects"] << " objects, " << m["elements"]
                << " elements, " << m["observations"] << " observations, " << m["robots"] << " robots, version "
                << m["version"] << (m.contains("node") ? ", node " + m["node"].get<std::string>() : "") << "\n";
    }
  });
}

int cluster(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/cluster")), [](const json& c) {
    std::cout << "cluster " << c["cluster"].get<std::string>() << " (asked node " << c["node"].get<std::string>()
              << "; leases of " << c["lease_ttl_s"] << " s)\n";
    for (const auto& n : c["nodes"]) {
      std::cout << "  " << n["node"].get<std::string>() << "  " << n["url"].get<std::string>() << "  "
                << (n["alive"].get<bool>() ? "alive" : "DEAD") << ", heartbeat " << std::fixed << std::setprecision(1)
                << n["heartbeat_age_s"].get<double>() << " s ago, maps:";
      for (const auto& m : n["maps"]) std::cout << " " << m.get<std::string>();
      std::cout << "\n";
    }
    for (const auto& l : c["leases"])
      std::cout << "  lease " << l["map"].get<std::string>() << ": node " << l["node"].get<std::string>() << ", epoch "
                << l["epoch"] << (l["live"].get<bool>() ? ", expires in " : ", EXPIRED ") << std::fixed
                << std::setprecision(1) << l["expires_in_s"].get<double>() << " s\n";
    if (!c["unowned"].empty()) {
      std::cout << "  waiting for a node:";
      for (const auto& m : c["unowned"]) std::cout << " " << m.get<std::string>();
      std::cout << "\n";
    }
    std::cout << "  this node: " << c["taken_over"] << " maps taken over, " << c["lost"] << " lost, "
              << c["handed_over"] << " handed over\n";
  });
}

int maps_create(const Invocation& in) {
  const json body = {{"id", in.operands[0]}};
  return in.emit(parse_answer(in.client.request("POST", "/api/v1/maps", body.dump(), "application/json", in.token)),
                 [](const json& m) { std::cout << "created map " << m["id"].get<std::string>() << "\n"; });
}

int maps_delete(const Invocation& in) {
  const auto answer = in.client.request("DELETE", "/api/v1/maps/" + in.operands[0], "", "application/json", in.token);
  return in.emit(parse_answer(answer),
                 [](const json& r) { std::cout << "deleted map " << r["deleted"].get<std::string>() << "\n"; });
}

int maps_import(const Invocation& in) {
  const auto target = "/api/v1/maps?prefix=" + in.flag("--prefix").value_or("");
  const auto answer = in.client.request("POST", target, read_file(in.operands[0]), "application/yaml", in.token);
  return in.emit(parse_answer(answer), [](const json& r) {
    for (const auto& m : r["maps"])
      std::cout << "created map " << m["id"].get<std::string>() << " (level " << m["level"].get<std::string>() << ", "
                << m["objects"] << " objects)\n";
  });
}

namespace {

// The subtasks and the components' parameters, as `network`, `network subtask` and `network set` print them.
void print_network_state(const json& n) {
  for (const auto& t : n.value("subtasks", json::array())) {
    std::cout << "subtask " << t["name"].get<std::string>() << ": " << (t["running"].get<bool>() ? "on" : "off")
              << ", components";
    for (const auto& c : t["components"]) std::cout << " " << c.get<std::string>();
    std::cout << "\n";
  }
  for (const auto& c : n.value("components", json::array())) {
    std::cout << "component " << c["name"].get<std::string>() << " (" << c["kind"].get<std::string>() << ")";
    for (const auto& [key, value] : c["params"].items()) std::cout << " " << key << "=" << value.get<std::string>();
    if (!c["running"].get<bool>()) std::cout << " [stopped]";
    std::cout << "\n";
  }
}

}  // namespace

int network(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/network")), [](const json& n) {
    std::cout << "network " << n["task_file"].get<std::string>() << "\n";
    for (const auto& e : n["executors"]) {
      std::cout << "executor " << e["name"].get<std::string>() << ": load " << std::fixed << std::setprecision(2)
                << e["load"].get<double>() << ", components";
      for (const auto& c : e["components"]) std::cout << " " << c.get<std::string>();
      std::cout << "\n";
    }
    for (const auto& f : n["functions"])
      std::cout << "  " << f["component"].get<std::string>() << "." << f["function"].get<std::string>() << " ("
                << f["ports"].size() + f["peeks"].size() << " ports, priority " << f["priority"]
                << "): " << f["activations"] << " activations, mean " << std::setprecision(3)
                << f["mean_ms"].get<double>() << " ms, " << f["failures"] << " failures\n";
    for (const auto& p : n["ports"])
      std::cout << "  " << p["component"].get<std::string>() << "." << p["port"].get<std::string>() << " ["
                << p["policy"].get<std::string>() << " " << p["capacity"] << "]: depth " << p["depth"] << " (max "
                << p["max_depth"] << "), " << p["pushed"] << " in, " << p["dropped"] << " dropped, " << p["refused"]
                << " refused"
                << (p.value("dropped_stopped", 0)
                        ? ", " + std::to_string(p["dropped_stopped"].get<std::uint64_t>()) + " dropped while stopped"
                        : std::string())
                << "\n";
    print_network_state(n);
  });
}

int network_subtask(const Invocation& in) {
  const auto& state = in.operands[1];
  if (state != "on" && state != "off") throw UsageError("network subtask: the state is on or off, not '" + state + "'");
  const json body = {{"running", state == "on"}};
  const auto answer =
      in.client.request("PUT", "/api/v1/network/subtasks/" + in.operands[0], body.dump(), "application/json", in.token);
  return in.emit(parse_answer(answer), [](const json& n) { print_network_state(n); });
}

int network_set(const Invocation& in) {
  json body = json::object();
  for (std::size_t i = 1; i < in.operands.size(); ++i) {
    const auto& word = in.operands[i];
    const auto eq = word.find('=');
    if (eq == std::string::npos || eq == 0) throw UsageError("network set: '" + word + "' is not KEY=VALUE");
    const auto value = word.substr(eq + 1);
    // A number goes as a number, anything else as text; the server checks it as a task file's value.
    const json number = json::parse(value, nullptr, false);
    body[word.substr(0, eq)] = !value.empty() && number.is_number() ? number : json(value);
  }
  const auto answer = in.client.request("PUT", "/api/v1/network/components/" + in.operands[0] + "/params", body.dump(),
                                        "application/json", in.token);
  return in.emit(parse_answer(answer), [](const json& n) { print_network_state(n); });
}

int floorplan_load(const Invocation& in) {
  // DXF and RMF files go in an import envelope with the options; JSON (plan or AMRL map) goes as it is.
  const std::string mapping_file = in.flag("--mapping").value_or("");
  const std::string units = in.flag("--units").value_or("");
  const std::string level = in.flag("--level").value_or("");
  const std::string& file = in.operands[0];
  auto extension = std::filesystem::path(file).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  std::string body = read_file(file);
  if (extension == ".dxf" || extension == ".yaml" || extension == ".yml") {
    // Ordered: the mapping's rules apply in file order.
    nlohmann::ordered_json spec = {{"format", extension == ".dxf" ? "dxf" : "rmf"},
                                   {"data", body},
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
  return in.emit(parse_answer(in.client.request("PUT", "/api/v1/floorplan", body, "application/json", in.token)),
                 [](const json& r) {
                   std::cout << "loaded floor plan '" << r["name"].get<std::string>() << "': " << r["objects"]
                             << " objects, " << r["edges"] << " edges (map version " << r["version"] << ")\n";
                   if (!r.contains("report")) return;
                   const auto& report = r["report"];
                   for (const auto& [type, count] : report["entity_counts"].items())
                     std::cout << "  " << type << ": " << count << "\n";
                   for (const auto& layer : report["unknown_layers"])
                     std::cout << "  unknown layer (skipped): " << layer.get<std::string>() << "\n";
                   for (const auto& warning : report["warnings"])
                     std::cout << "  warning: " << warning.get<std::string>() << "\n";
                 });
}

int floorplan_show(const Invocation& in) {
  // Always JSON: the plan is the document the user loaded.
  std::cout << parse_answer(in.client.request("GET", "/api/v1/floorplan")).dump(2) << "\n";
  return kExitOk;
}

int primitives_post(const Invocation& in) {
  const auto answer =
      in.client.request("POST", "/api/v1/primitives", read_file(in.operands[0]), "application/json", in.token);
  return in.emit(parse_answer(answer), [](const json& r) {
    std::cout << "observation " << r["seq"] << " applied, map version " << r["version"] << "\n";
    for (const auto& d : r["decisions"]) print_decision(d);
  });
}

int map(const Invocation& in) {
  const auto format = in.flag("--format");
  const auto out = in.flag("--out");
  if (format.has_value() != out.has_value()) throw UsageError("map: --format and --out go together");
  // The server checks the box and names what is wrong with it.
  const auto bbox = in.flag("--bbox");
  const std::string box_query = bbox ? "bbox=" + *bbox : "";
  if (!format)
    return in.emit(parse_answer(in.client.request("GET", "/api/v1/map" + (bbox ? "?" + box_query : ""))), print_map);
  const auto answer = in.client.request("GET", "/api/v1/map?format=" + *format + (bbox ? "&" + box_query : ""));
  save(answer, *out);
  std::cout << "wrote " << *out << " (" << answer.body.size() << " bytes)\n";
  return kExitOk;
}

int map_quality(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/map/quality")), [](const json& q) {
    std::cout << "map version " << q["map_version"].get<std::int64_t>() << ", grid revision "
              << q["grid_revision"].get<std::int64_t>() << "\n"
              << "  elements      " << q["elements"] << " (" << fixed(q["total_length_m"].get<double>(), 1)
              << " m, median " << fixed(q["median_length_m"].get<double>()) << " m, "
              << fixed(q["elements_per_m"].get<double>(), 3) << " per m)\n"
              << "  precision     " << fixed(q["precision"].get<double>(), 3)
              << "  (element length on occupied cells)\n"
              << "  recall        " << fixed(q["recall"].get<double>(), 3) << "  (occupied cells near an element, of "
              << q["occupied_cells"] << ")\n"
              << "  redundancy    " << fixed(q["redundancy"].get<double>(), 3)
              << "  (element length lying on another element)\n"
              << "  calibration   "
              << (q["calibration"].is_null() ? std::string("-") : fixed(q["calibration"].get<double>(), 3))
              << "  (scan lines inside the 95 % gate of their element, of " << q["calibration_samples"]
              << "; honest about 0.95)\n";
  });
}

int report(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/report/as-built")), [](const json& r) {
    const auto& s = r["summary"];
    std::cout << "plan '" << r["plan"].get<std::string>() << "': " << s["objects"] << " objects, " << s["confirmed"]
              << " confirmed, " << s["moved"] << " moved, " << s.value("missing", 0) << " missing, "
              << s.value("partly_missing", 0) << " partly missing, " << s.value("gone", 0) << " gone, "
              << s["never_observed"] << " never observed; " << s["not_in_plan"]
              << " observed elements not in the plan\n";
    for (const auto& o : r["objects"]) {
      const auto status = o["status"].get<std::string>();
      if (status == "moved") {
        std::cout << "  moved: " << o["id"].get<std::string>() << " by " << o["moved_by"]["distance"].get<double>()
                  << " m, " << o["moved_by"]["dtheta"].get<double>() << " rad\n";
      } else if (o.contains("verdicts")) {
        for (const auto& v : o["verdicts"])
          std::cout << "  " << v["verdict"].get<std::string>() << ": " << o["id"].get<std::string>()
                    << (v.contains("edge") ? " edge " + v["edge"].get<std::string>() : std::string()) << "\n";
      }
    }
  });
}

namespace {

void print_changes(const json& r) {
  const auto& list = r["changes"];
  std::cout << list.size() << " changes between the plan and the building (map version " << r["version"]
            << ", grid revision " << r["grid_revision"] << ")\n";
  for (const auto& c : list) {
    std::cout << "  " << c["id"].get<std::string>() << "  " << std::left << std::setw(20)
              << c["kind"].get<std::string>() << std::right << " " << c["key"].get<std::string>() << "  " << std::fixed
              << std::setprecision(2) << c["length"].get<double>() << " m, confidence " << std::setprecision(0)
              << 100 * c["confidence"].get<double>() << " %\n"
              << std::defaultfloat << std::setprecision(6);
    std::cout << "      " << c["explanation"].get<std::string>() << "\n";
  }
  if (!list.empty()) std::cout << "accept or reject one with: wmctl changes accept|reject ID\n";
}

void print_change_outcome(const json& r) {
  const auto& d = r["decision"];
  std::cout << d["action"].get<std::string>() << " (" << d["rule"].get<std::string>() << "), map version "
            << r["version"] << ": " << d["explanation"].get<std::string>() << "\n";
  if (r.contains("object")) std::cout << "new plan object: " << r["object"].get<std::string>() << "\n";
}

}  // namespace

int changes(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/changes")), print_changes);
}

int changes_accept(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("POST", "/api/v1/changes/" + in.operands[0] + "/accept", "{}",
                                                "application/json", in.token)),
                 print_change_outcome);
}

int changes_reject(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("POST", "/api/v1/changes/" + in.operands[0] + "/reject", "{}",
                                                "application/json", in.token)),
                 print_change_outcome);
}

int changes_undo(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("POST", "/api/v1/changes/undo", "{}", "application/json", in.token)),
                 print_change_outcome);
}

int grid(const Invocation& in) {
  const auto out = in.flag("--out");  // required in the command table
  const std::string layer = in.flag("--layer").value_or("bayes");
  const std::string bbox = in.flag("--bbox").value_or("");
  const std::string query = "?layer=" + layer + (bbox.empty() ? "" : "&bbox=" + bbox);
  const auto image = in.client.request("GET", "/api/v1/grid" + query + "&format=pgm");
  save(image, *out);
  std::cout << "wrote " << *out << " (" << image.body.size() << " bytes)\n";
  if (layer == "bayes") {
    // map_server reads the image path relative to the YAML file.
    const auto yaml =
        in.client.request("GET", "/api/v1/grid/map.yaml" + (bbox.empty() ? std::string() : "?bbox=" + bbox));
    if (yaml.status != 200) parse_answer(yaml);
    std::string text = yaml.body;
    const auto at = text.find("image: map.pgm");
    if (at != std::string::npos) text.replace(at, 14, "image: " + std::filesystem::path(*out).filename().string());
    const auto yaml_path = std::filesystem::path(*out).replace_extension(".yaml").string();
    write_file(yaml_path, text);
    std::cout << "wrote " << yaml_path << "\n";
  }
  return kExitOk;
}

int robots(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/robots")), [](const json& r) {
    if (r["robots"].empty()) std::cout << "no robot has sent anything yet\n";
    for (const auto& robot : r["robots"]) {
      std::cout << std::left << std::setw(16) << robot["id"].get<std::string>() << " " << std::setw(7)
                << robot["status"].get<std::string>();
      if (robot["pose"].is_null()) {
        std::cout << " no pose";
      } else {
        const auto& p = robot["pose"];
        std::cout << " at (" << fixed(p["x"].get<double>()) << ", " << fixed(p["y"].get<double>()) << ") θ "
                  << fixed(p["theta"].get<double>()) << " from " << p["via"].get<std::string>();
      }
      std::cout << ", silent " << fixed(robot["silent_s"].get<double>()) << " s: ";
      for (const auto& [sensor, count] : robot["scans"].items()) std::cout << count << " " << sensor << " scans, ";
      std::cout << robot["primitives"] << " primitives, " << robot["poses"] << " poses\n";
    }
  });
}

int grid_extract(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("POST", "/api/v1/grid/extract", "{}", "application/json", in.token)),
                 [](const json& r) {
                   if (r["observation"].is_null()) {
                     std::cout << "no lines in the grid\n";
                     return;
                   }
                   std::cout << r["segments"] << " grid lines, observation " << r["observation"] << "\n";
                   for (const auto& d : r["decisions"]) print_decision(d);
                 });
}

}  // namespace wm::wmctl
