// wmctl commands about decisions and rules: the decision log, element histories, rule files, dry runs, queries.
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>

#include "clients/wmctl/commands.h"

namespace wm::wmctl {
namespace {

// Element ids are "e<n>"; everything else is taken as a CAD object id.
std::string history_target(const std::string& id) {
  const bool element = id.size() > 1 && id[0] == 'e' && id.find_first_not_of("0123456789", 1) == std::string::npos;
  return std::string(element ? "/api/v1/elements/" : "/api/v1/objects/") + id + "/history";
}

// The state of a line element or an object before or after a decision, with its standard deviations; the extent
// of an element for a trim.
std::string numbers(const json& state) {
  std::ostringstream out;
  out << std::setprecision(4);
  if (state.contains("rho")) {
    out << "rho " << state["rho"].get<double>() << " m, phi " << state["phi"].get<double>() << " rad, sigma_rho "
        << std::sqrt(state["cov"][0][0].get<double>()) << " m, sigma_phi "
        << std::sqrt(state["cov"][1][1].get<double>()) << " rad";
  } else if (state.contains("pose")) {
    out << "pose (" << state["pose"]["x"].get<double>() << ", " << state["pose"]["y"].get<double>() << ", "
        << state["pose"]["theta"].get<double>() << "), sigma_xy " << std::sqrt(state["pose_cov"][0][0].get<double>())
        << " m";
  } else if (state.contains("p0")) {
    out << "from (" << state["p0"][0].get<double>() << ", " << state["p0"][1].get<double>() << ") to ("
        << state["p1"][0].get<double>() << ", " << state["p1"][1].get<double>() << ") m";
  }
  return out.str();
}

void print_history(const json& r) {
  std::cout << r["id"].get<std::string>() << (r["exists"].get<bool>() ? "" : " (no longer in the map)") << ": "
            << r["decisions"].size() << " decisions\n";
  for (const auto& d : r["decisions"]) {
    print_decision(d);
    std::cout << "      observation " << d["observation"] << " by " << d["observer"].get<std::string>() << " ("
              << d["origin"].get<std::string>() << ", sensor " << d["sensor"].get<std::string>() << ")";
    if (!d["mahalanobis_sq"].is_null()) std::cout << ", d2 " << d["mahalanobis_sq"].get<double>();
    std::cout << "\n";
    if (d.contains("before")) std::cout << "      before: " << numbers(d["before"]) << "\n";
    if (d.contains("after")) std::cout << "      after:  " << numbers(d["after"]) << "\n";
  }
  // An object's standing against the grid now: how much of each edge was seen, backed, seen through.
  if (!r.contains("as_built")) return;
  const auto& a = r["as_built"];
  std::cout << "status: " << a["status"].get<std::string>() << "\n";
  if (a.contains("edges")) {
    for (const auto& e : a["edges"]) {
      const double length = e["length"].get<double>();
      std::cout << std::fixed << std::setprecision(2) << "  edge " << e["edge"] << ": " << length << " m, observed "
                << 100 * e["observed"].get<double>() << " %, backed by occupied cells over "
                << e["backed"].get<double>() * length << " m, seen through over "
                << e["seen_through"].get<double>() * length << " m; " << e["beams_through"]
                << " beams passed through it, " << e["beams_ended"] << " returned on it";
      for (const auto& s : e["seen_through_stretches"])
        std::cout << "\n    seen through from " << s["s0"].get<double>() << " to " << s["s1"].get<double>() << " m, by "
                  << s["beams_through"] << " beams, " << s.value("beams_ended", 0) << " returned on it";
      std::cout << std::defaultfloat << std::setprecision(6) << "\n";
    }
  }
  if (a.contains("verdicts"))
    for (const auto& v : a["verdicts"])
      std::cout << "  verdict " << v["verdict"].get<std::string>() << " (" << v["rule"].get<std::string>()
                << "): " << v["explanation"].get<std::string>() << "\n";
}

void print_rules(const json& r) {
  std::cout << "generation " << r["generation"] << "\n";
  for (const auto& f : r["files"])
    std::cout << "  " << f["path"].get<std::string>() << "  sha256 " << f["checksum"].get<std::string>().substr(0, 12)
              << "\n";
  if (!r["last_error"].get<std::string>().empty())
    std::cout << "last error:\n" << r["last_error"].get<std::string>() << "\n";
}

void print_dry_run(const json& r) {
  std::cout << r["redecided"] << " decisions re-decided with " << r["file"].get<std::string>() << ": " << r["changed"]
            << " would change\n";
  for (const auto& c : r["changes"]) {
    const auto& old = c["recorded"];
    const auto& now = c["candidate"];
    std::cout << "  #" << old["seq"] << " " << old["action"].get<std::string>() << " by "
              << old["rule"].get<std::string>() << "  ->  " << now["action"].get<std::string>() << " by "
              << now["rule"].get<std::string>() << "\n      " << now["explanation"].get<std::string>() << "\n";
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

}  // namespace

int decisions(const Invocation& in) {
  // Every flag given is passed on, in order, as the query parameter of its name.
  std::string query;
  for (const auto& [flag, value] : in.flags) query += (query.empty() ? "?" : "&") + flag.substr(2) + "=" + value;
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/decisions" + query)), [](const json& r) {
    for (const auto& d : r["decisions"]) print_decision(d);
    std::cout << r["decisions"].size() << " decisions\n";
  });
}

int explain(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", history_target(in.operands[0]))), print_history);
}

int rules(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("GET", "/api/v1/rules")), print_rules);
}

int rules_reload(const Invocation& in) {
  return in.emit(parse_answer(in.client.request("POST", "/api/v1/rules/reload", "{}", "application/json", in.token)),
                 [](const json& r) {
                   std::cout << "rules reloaded (generation " << r["generation"] << ")\n";
                   print_rules(r);
                 });
}

int rules_dry_run(const Invocation& in) {
  const std::string& file = in.operands[0];
  json body = {{"file", std::filesystem::path(file).filename().string()}, {"text", read_file(file)}};
  if (const auto last = in.flag("--last")) body["last"] = parse_count(*last);
  return in.emit(
      parse_answer(in.client.request("POST", "/api/v1/rules/dry-run", body.dump(), "application/json", in.token)),
      print_dry_run);
}

int query(const Invocation& in) {
  json body = {{"goal", in.operands[0]}};
  if (const auto max = in.flag("--max")) body["max_solutions"] = parse_count(*max);
  return in.emit(parse_answer(in.client.request("POST", "/api/v1/query", body.dump())), print_query);
}

}  // namespace wm::wmctl
