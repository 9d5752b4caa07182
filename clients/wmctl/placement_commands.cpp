// Where the floor plan sits in the world: align, place, pairs, undo, redecide, georeference.
#include <cmath>
#include <iostream>
#include <sstream>

#include "clients/wmctl/commands.h"

namespace wm::wmctl {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

double parse_number(const std::string& text, const std::string& what) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || !std::isfinite(v)) throw UsageError(what + ": '" + text + "' is not a number");
  return v;
}

std::string placement_line(const json& p) {
  return "x " + fixed(p["x"].get<double>()) + " m, y " + fixed(p["y"].get<double>()) + " m, theta " +
         fixed(p["theta"].get<double>() / kDeg, 3) + " deg, scale " + fixed(p["scale"].get<double>(), 6);
}

void print_placement_outcome(const json& r) {
  std::cout << "placement now " << placement_line(r["placement"]) << " (was " << placement_line(r["before"])
            << "), map version " << r["version"] << "\n";
  print_decision(r["decision"]);
}

void print_redecided(const json& r) {
  std::cout << "re-decided " << r["elements"] << " elements: " << r["changed"] << " changed";
  for (const auto& [action, n] : r["actions"].items()) std::cout << ", " << action << " " << n;
  std::cout << "\n";
}

json post(const Invocation& in, const std::string& path, const json& body) {
  return parse_answer(in.client.request("POST", path, body.dump(), "application/json", in.token));
}

}  // namespace

int floorplan_align(const Invocation& in) {
  json body = json::object();
  if (in.flag("--apply")) body["apply"] = true;
  if (in.flag("--apply-ambiguous")) body["apply_ambiguous"] = true;
  if (in.flag("--redecide")) body["redecide"] = true;
  if (const auto v = in.flag("--max-translation")) body["max_translation_m"] = parse_number(*v, "--max-translation");
  if (const auto v = in.flag("--max-rotation")) body["max_rotation_deg"] = parse_number(*v, "--max-rotation");
  if (const auto v = in.flag("--min-score")) body["min_score"] = parse_number(*v, "--min-score");
  if (const auto v = in.flag("--time-budget")) body["time_budget_ms"] = parse_number(*v, "--time-budget");
  if (const auto v = in.flag("--scale")) {
    if (*v == "units") {
      body["scale"] = "units";
    } else if (const auto comma = v->find(','); comma != std::string::npos) {
      body["scale"] = {parse_number(v->substr(0, comma), "--scale"), parse_number(v->substr(comma + 1), "--scale")};
    } else {
      body["scale"] = parse_number(*v, "--scale");
    }
  }
  return in.emit(post(in, "/api/v1/floorplan/align", body), [](const json& r) {
    const auto& best = r["best"];
    std::cout << "best:      " << placement_line(best) << "\n"
              << "           score " << fixed(best["score"].get<double>()) << " (share of the seen plan on occupied "
              << "cells), coverage " << fixed(best["coverage"].get<double>()) << ", rms " << fixed(r["rms_m"], 4)
              << " m, sigma x " << fixed(std::sqrt(r["cov"][0][0].get<double>()), 4) << " m, sigma theta "
              << fixed(std::sqrt(r["cov"][2][2].get<double>()) / kDeg, 4) << " deg\n";
    if (r["runner_up"].is_null())
      std::cout << "runner-up: none within 0.7 of the best's search score\n";
    else
      std::cout << "runner-up: " << placement_line(r["runner_up"]) << ", score "
                << fixed(r["runner_up"]["score"].get<double>()) << ", coverage "
                << fixed(r["runner_up"]["coverage"].get<double>()) << "\n";
    std::cout << "searched " << r["edges"] << " edges in " << fixed(r["seconds"].get<double>()) << " s ("
              << r["hypotheses_scored"] << " hypotheses)" << (r["ambiguous"].get<bool>() ? ", AMBIGUOUS" : "") << "\n"
              << "verdict: " << r["verdict"].get<std::string>();
    if (r["verdict"] == "preview") std::cout << " (nothing changed; --apply puts it in force)";
    if (r["verdict"] == "ambiguous") std::cout << " (nothing changed; --apply-ambiguous applies it anyway)";
    if (r["verdict"] == "low_score" && r["best"]["coverage"].get<double>() == 0)
      std::cout << " (nothing changed: within the bounds the plan overlaps nothing the robots saw)";
    else if (r["verdict"] == "low_score")
      std::cout << " (nothing changed: is this the building the robots saw?)";
    std::cout << "\n";
    if (r.contains("decision")) print_decision(r["decision"]);
    if (r.contains("redecided")) print_redecided(r["redecided"]);
  });
}

int floorplan_place(const Invocation& in) {
  json body = {{"x", parse_number(in.operands[0], "X")},
               {"y", parse_number(in.operands[1], "Y")},
               {"theta_deg", parse_number(in.operands[2], "THETA_DEG")}};
  if (const auto v = in.flag("--scale")) body["scale"] = parse_number(*v, "--scale");
  return in.emit(post(in, "/api/v1/floorplan/place", body), print_placement_outcome);
}

int floorplan_pairs(const Invocation& in) {
  std::istringstream lines(read_file(in.operands[0]));
  json pairs = json::array();
  std::string line;
  int number = 0;
  while (std::getline(lines, line)) {
    ++number;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream words(line);
    std::vector<std::string> fields;
    for (std::string w; words >> w;) fields.push_back(w);
    if (fields.empty()) continue;
    if (fields.size() != 4)
      throw UsageError(in.operands[0] + ":" + std::to_string(number) + ": expected 'plan_x plan_y world_x world_y'");
    const auto at = in.operands[0] + ":" + std::to_string(number);
    pairs.push_back({{"plan", {parse_number(fields[0], at), parse_number(fields[1], at)}},
                     {"world", {parse_number(fields[2], at), parse_number(fields[3], at)}}});
  }
  const json body = {{"pairs", pairs}, {"scale", in.flag("--scale").has_value()}, {"apply", !in.flag("--preview")}};
  return in.emit(post(in, "/api/v1/floorplan/pairs", body), [](const json& r) {
    std::cout << r["pairs"] << " pairs: " << placement_line(r["placement"]) << ", rms " << fixed(r["rms_m"], 4)
              << " m\n";
    if (r["applied"].get<bool>())
      print_decision(r["decision"]);
    else
      std::cout << "preview: nothing changed\n";
  });
}

int floorplan_undo(const Invocation& in) {
  return in.emit(post(in, "/api/v1/floorplan/undo", json::object()), print_placement_outcome);
}

int floorplan_redecide(const Invocation& in) {
  return in.emit(post(in, "/api/v1/floorplan/redecide", json::object()), print_redecided);
}

int floorplan_georeference(const Invocation& in) {
  if (in.flag("--clear")) {
    const auto r =
        parse_answer(in.client.request("DELETE", "/api/v1/floorplan/georeference", "{}", "application/json", in.token));
    return in.emit(r, [](const json&) { std::cout << "georeference removed: exports are in local metres\n"; });
  }
  if (!in.flag("--lat") || !in.flag("--lon"))
    throw UsageError("floorplan georeference needs --lat and --lon, or --clear");
  json body = {{"latitude", parse_number(*in.flag("--lat"), "--lat")},
               {"longitude", parse_number(*in.flag("--lon"), "--lon")}};
  if (const auto v = in.flag("--heading")) body["heading"] = parse_number(*v, "--heading");
  const auto r = parse_answer(
      in.client.request("PUT", "/api/v1/floorplan/georeference", body.dump(), "application/json", in.token));
  return in.emit(r, [](const json& a) {
    std::cout << "georeference set: origin at " << a["georeference"]["latitude"] << ", "
              << a["georeference"]["longitude"] << ", x axis bearing " << a["georeference"]["heading"] << " deg\n";
  });
}

}  // namespace wm::wmctl
