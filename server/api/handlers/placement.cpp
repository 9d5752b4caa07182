// Where the floor plan sits in the world: an explicit placement, one from point pairs, one the grid search finds;
// undo; re-deciding the observed elements against the plan as placed; the world frame's georeference.
#include <cmath>
#include <map>
#include <numbers>

#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/json/codec.h"

namespace wm::api {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Coordinates a placement or a pair may have [m]: the floor plan's own limit.
constexpr double kMaxCoordinate = 1e5;

// A finite number at `key`, or `fallback` when absent. @throw ApiError 400.
double number_field(const nlohmann::json& doc, const std::string& key, std::optional<double> fallback = std::nullopt) {
  if (!doc.contains(key)) {
    if (fallback) return *fallback;
    throw bad_request(key, "missing");
  }
  const auto& v = doc[key];
  if (!v.is_number() || !std::isfinite(v.get<double>())) throw bad_request(key, "expected a finite number");
  return v.get<double>();
}

bool bool_field(const nlohmann::json& doc, const std::string& key, bool fallback) {
  if (!doc.contains(key)) return fallback;
  if (!doc[key].is_boolean()) throw bad_request(key, "expected true or false");
  return doc[key].get<bool>();
}

Eigen::Vector2d point_field(const nlohmann::json& v, const std::string& path) {
  if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
    throw bad_request(path, "expected [x, y] with finite numbers");
  const double x = v[0].get<double>(), y = v[1].get<double>();
  if (!std::isfinite(x) || !std::isfinite(y) || std::abs(x) > kMaxCoordinate || std::abs(y) > kMaxCoordinate)
    throw bad_request(path, "expected [x, y] with finite numbers within ±1e5");
  return {x, y};
}

double scale_value(double scale, const std::string& path) {
  if (!(scale >= 1e-6) || scale > 1e6) throw bad_request(path, "expected a scale in [1e-6, 1e6]");
  return scale;
}

// "theta" [rad] or "theta_deg".
double heading_field(const nlohmann::json& doc) {
  if (doc.contains("theta") && doc.contains("theta_deg"))
    throw bad_request("theta", "give theta or theta_deg, not both");
  if (doc.contains("theta_deg")) return number_field(doc, "theta_deg") * kDeg;
  return number_field(doc, "theta");
}

// A 4×4 covariance over (x, y, θ, scale): symmetric, finite, non-negative diagonal.
Eigen::Matrix4d cov_field(const nlohmann::json& doc) {
  if (!doc.contains("cov")) return Eigen::Vector4d(1e-4, 1e-4, 1e-6, 0).asDiagonal();  // 1 cm, 0.06°: by hand
  const auto& v = doc["cov"];
  Eigen::Matrix4d cov;
  if (!v.is_array() || v.size() != 4)
    throw bad_request("cov", "expected 4 rows of 4 numbers over (x, y, theta, scale)");
  for (int r = 0; r < 4; ++r) {
    const auto& row = v[static_cast<std::size_t>(r)];
    if (!row.is_array() || row.size() != 4) throw bad_request("cov", "expected 4 rows of 4 numbers");
    for (int c = 0; c < 4; ++c) {
      const auto& x = row[static_cast<std::size_t>(c)];
      if (!x.is_number() || !std::isfinite(x.get<double>())) throw bad_request("cov", "expected finite numbers");
      cov(r, c) = x.get<double>();
    }
  }
  if (!cov.isApprox(cov.transpose()) || (cov.diagonal().array() < 0).any())
    throw bad_request("cov", "expected a symmetric matrix with a non-negative diagonal");
  return cov;
}

nlohmann::json placement_outcome_json(const service::PlacementOutcome& outcome) {
  auto decision = json_codec::decision_json(outcome.decision);
  return {{"version", outcome.version},
          {"placement", decision["after"]},
          {"before", decision["before"]},
          {"decision", decision}};
}

nlohmann::json redecide_json(const service::RedecideOutcome& outcome) {
  nlohmann::json decisions = nlohmann::json::array();
  std::map<std::string, int> actions;
  for (const auto& d : outcome.decisions) {
    decisions.push_back(json_codec::decision_json(d));
    ++actions[std::string(rules::wire_name(d.action))];
  }
  return {{"elements", outcome.elements},
          {"changed", outcome.decisions.size()},
          {"actions", actions},
          {"version", outcome.version},
          {"decisions", decisions}};
}

nlohmann::json hypothesis_json(const fusion::PlacementHypothesis& h) {
  return {{"x", h.placement.x_m},       {"y", h.placement.y_m}, {"theta", h.placement.theta_rad},
          {"scale", h.placement.scale}, {"score", h.score},     {"coverage", h.coverage}};
}

std::string observer_of(const nlohmann::json& doc) { return json_codec::observer_of(doc).value_or("client"); }

}  // namespace

Response post_floor_plan_place(const Call& call) {
  require_token(call.request, call.options);
  const auto doc = parse_json_object(call.request);
  require_known_keys(doc, {"x", "y", "theta", "theta_deg", "scale", "cov", "observer", "source"});
  world::PlacementChange change;
  change.placement = {number_field(doc, "x"), number_field(doc, "y"), heading_field(doc),
                      scale_value(number_field(doc, "scale", 1.0), "scale")};
  if (std::abs(change.placement.x_m) > kMaxCoordinate || std::abs(change.placement.y_m) > kMaxCoordinate)
    throw bad_request("x", "expected x and y within ±1e5 m");
  if (std::abs(change.placement.theta_rad) > 1e3) throw bad_request("theta", "expected an angle within ±1000 rad");
  change.cov = cov_field(doc);
  change.rule = "plan_placed";
  change.explanation = "placed by hand";
  change.observer = observer_of(doc);
  return json_response(call.request, placement_outcome_json(call.world.plan.place_floor_plan(change, doc.dump())));
}

Response post_floor_plan_pairs(const Call& call) {
  require_token(call.request, call.options);
  const auto doc = parse_json_object(call.request);
  require_known_keys(doc, {"pairs", "scale", "sigma", "apply", "observer", "source"});
  if (!doc.contains("pairs") || !doc["pairs"].is_array()) throw bad_request("pairs", "expected an array of pairs");
  if (doc["pairs"].size() > 10000) throw bad_request("pairs", "at most 10000 pairs");
  std::vector<fusion::PointPair> pairs;
  for (std::size_t i = 0; i < doc["pairs"].size(); ++i) {
    const auto& p = doc["pairs"][i];
    const auto path = "pairs[" + std::to_string(i) + "]";
    if (!p.is_object() || !p.contains("plan") || !p.contains("world"))
      throw bad_request(path, "expected {\"plan\": [x, y], \"world\": [x, y]}");
    pairs.push_back({point_field(p["plan"], path + ".plan"), point_field(p["world"], path + ".world")});
  }
  const double sigma = number_field(doc, "sigma", 0.05);
  if (!(sigma > 0) || sigma > 100) throw bad_request("sigma", "expected a number in (0, 100] [m]");
  const auto placed = fusion::place_from_pairs(pairs, bool_field(doc, "scale", false), sigma);
  const auto& p = placed.placement;
  if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.theta_rad) || !(p.scale >= 1e-6) ||
      p.scale > 1e6 || !placed.covariance.allFinite() || std::abs(p.x_m) > kMaxCoordinate ||
      std::abs(p.y_m) > kMaxCoordinate)
    throw bad_request("pairs", "the pairs give no usable placement (scale outside [1e-6, 1e6] or beyond ±1e5 m)");
  nlohmann::json answer = {{"placement", json_codec::placement_json(placed.placement, placed.covariance)},
                           {"rms_m", placed.rms_m},
                           {"pairs", pairs.size()},
                           {"applied", false}};
  if (bool_field(doc, "apply", true)) {
    world::PlacementChange change;
    change.placement = placed.placement;
    change.cov = placed.covariance;
    change.rule = "plan_paired";
    change.explanation = std::to_string(pairs.size()) + " point pairs, rms " + std::to_string(placed.rms_m) + " m";
    change.observer = observer_of(doc);
    answer["applied"] = true;
    answer.update(placement_outcome_json(call.world.plan.place_floor_plan(change, doc.dump())));
  }
  return json_response(call.request, answer);
}

Response post_floor_plan_align(const Call& call) {
  require_token(call.request, call.options);
  const auto doc = parse_json_object(call.request);
  require_known_keys(doc, {"max_translation_m", "max_rotation_deg", "scale", "apply", "apply_ambiguous", "min_score",
                           "min_coverage", "redecide", "time_budget_ms", "observer", "source"});
  service::AlignRequest request;
  auto& search = request.search;
  search.max_translation_m = number_field(doc, "max_translation_m", 10.0);
  if (search.max_translation_m < 0 || search.max_translation_m > 1000)
    throw bad_request("max_translation_m", "expected a number in [0, 1000]");
  const double rotation_deg = number_field(doc, "max_rotation_deg", 180.0);
  if (rotation_deg < 0 || rotation_deg > 180) throw bad_request("max_rotation_deg", "expected a number in [0, 180]");
  search.max_rotation_rad = rotation_deg * kDeg;
  request.scale_given = doc.contains("scale");
  if (doc.contains("scale")) {
    const auto& s = doc["scale"];
    if (s.is_string() && s.get<std::string>() == "units") {
      // The unit factors a drawing's stated units may be wrong by: m, cm, mm, in, ft, and their inverses.
      search.scale_candidates = {1.0, 0.01, 0.001, 0.0254, 0.3048, 100.0, 1000.0, 1 / 0.0254, 1 / 0.3048};
    } else if (s.is_number()) {
      search.scale_min = search.scale_max = scale_value(number_field(doc, "scale"), "scale");
    } else if (s.is_array() && s.size() == 2 && s[0].is_number() && s[1].is_number()) {
      search.scale_min = scale_value(s[0].get<double>(), "scale[0]");
      search.scale_max = scale_value(s[1].get<double>(), "scale[1]");
      if (search.scale_min > search.scale_max) throw bad_request("scale", "expected [min, max] with min <= max");
    } else {
      throw bad_request("scale", "expected a number, [min, max] or \"units\"");
    }
  }
  const double budget_ms = number_field(doc, "time_budget_ms", 10000.0);
  if (budget_ms < 1 || budget_ms > 30000) throw bad_request("time_budget_ms", "expected a number in [1, 30000]");
  search.time_budget = std::chrono::milliseconds(static_cast<std::int64_t>(budget_ms));
  request.apply = bool_field(doc, "apply", false);
  request.apply_ambiguous = bool_field(doc, "apply_ambiguous", false);
  request.redecide = bool_field(doc, "redecide", false);
  request.min_score = number_field(doc, "min_score", 0.5);
  if (request.min_score < 0 || request.min_score > 1) throw bad_request("min_score", "expected a number in [0, 1]");
  request.min_coverage = number_field(doc, "min_coverage", 0.05);
  if (request.min_coverage < 0 || request.min_coverage > 1)
    throw bad_request("min_coverage", "expected a number in [0, 1]");
  request.observer = observer_of(doc);
  const auto outcome = call.world.plan.align_floor_plan(request);
  const auto& r = outcome.result;
  nlohmann::json answer = {
      {"verdict", outcome.verdict},
      {"applied", outcome.applied},
      {"best", hypothesis_json(r.best)},
      {"runner_up", r.runner_up ? hypothesis_json(*r.runner_up) : nlohmann::json(nullptr)},
      {"ambiguous", r.ambiguous},
      {"cov", json_codec::placement_json(r.best.placement, r.covariance)["cov"]},
      {"rms_m", r.rms_m},
      {"matched_points", r.matched_points},
      {"edges", outcome.edges},
      {"hypotheses_scored", r.hypotheses_scored},
      {"seconds", r.seconds},
      {"timed_out", r.timed_out},
      {"before", json_codec::placement_json(outcome.before, Eigen::Matrix4d::Zero())},
      {"bounds",
       {{"max_translation_m", search.max_translation_m},
        {"max_rotation_deg", rotation_deg},
        {"scale", search.scale_candidates.empty() ? nlohmann::json::array({search.scale_min, search.scale_max})
                                                  : nlohmann::json(search.scale_candidates)}}}};
  if (outcome.placement) answer["decision"] = json_codec::decision_json(outcome.placement->decision);
  if (outcome.placement) answer["version"] = outcome.placement->version;
  if (outcome.redecided) answer["redecided"] = redecide_json(*outcome.redecided);
  return json_response(call.request, answer);
}

Response post_floor_plan_undo(const Call& call) {
  require_token(call.request, call.options);
  return json_response(call.request, placement_outcome_json(call.world.plan.undo_placement("client")));
}

Response post_floor_plan_redecide(const Call& call) {
  require_token(call.request, call.options);
  return json_response(call.request, redecide_json(call.world.plan.redecide_elements("client")));
}

Response put_georeference(const Call& call) {
  require_token(call.request, call.options);
  const auto doc = parse_json_object(call.request);
  require_known_keys(doc, {"latitude", "longitude", "heading"});
  const apriori::Georeference g{number_field(doc, "latitude"), number_field(doc, "longitude"),
                                number_field(doc, "heading", 90.0)};
  try {
    apriori::validate(g);
  } catch (const std::invalid_argument& e) {
    throw bad_request("", e.what());
  }
  const auto version = call.world.plan.set_georeference(g);
  return json_response(call.request, {{"version", version}, {"georeference", json_codec::georeference_json(g)}});
}

Response delete_georeference(const Call& call) {
  require_token(call.request, call.options);
  const auto version = call.world.plan.set_georeference(std::nullopt);
  return json_response(call.request, {{"version", version}, {"georeference", nullptr}});
}

}  // namespace wm::api
