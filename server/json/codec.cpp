#include "server/json/codec.h"

#include <cmath>
#include <regex>

#include "server/api/api_error.h"

namespace wm::json_codec {
namespace {

using nlohmann::json;

std::string field(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string item(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

double finite_number(const json& value, const std::string& path, double limit) {
  if (!value.is_number()) throw api::bad_request(path, "expected a number");
  const double v = value.get<double>();
  if (!std::isfinite(v)) throw api::bad_request(path, "not a finite number");
  if (std::abs(v) > limit) throw api::bad_request(path, "absurd value");
  return v;
}

Eigen::Vector2d point(const json& value, const std::string& path, double limit) {
  if (!value.is_array() || value.size() != 2) throw api::bad_request(path, "expected a point [x, y]");
  return {finite_number(value[0], item(path, 0), limit), finite_number(value[1], item(path, 1), limit)};
}

Eigen::Matrix2d covariance(const json& value, const std::string& path) {
  if (!value.is_array() || value.size() != 2) throw api::bad_request(path, "expected a 2x2 matrix [[a, b], [b, c]]");
  Eigen::Matrix2d m;
  for (int r = 0; r < 2; ++r) {
    if (!value[r].is_array() || value[r].size() != 2) throw api::bad_request(item(path, r), "expected 2 numbers");
    for (int c = 0; c < 2; ++c) m(r, c) = finite_number(value[r][c], item(item(path, r), c), 1e6);
  }
  if (std::abs(m(0, 1) - m(1, 0)) > 1e-12 * std::max(1.0, std::abs(m(0, 1)))) throw api::bad_request(path, "not symmetric");
  if (m(0, 0) <= 0.0 || m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0) <= 0.0) throw api::bad_request(path, "not positive definite");
  return m;
}

json point_json(const Eigen::Vector2d& p) { return json::array({p.x(), p.y()}); }

json matrix_json(const Eigen::MatrixXd& m) {
  json rows = json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    json row = json::array();
    for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(std::move(row));
  }
  return rows;
}

json segment_json(const fusion::LineSegment& s) {
  return {{"p0", point_json(s.p0())}, {"p1", point_json(s.p1())}, {"rho", s.line.rho_m},
          {"phi", s.line.phi_rad},    {"cov", matrix_json(s.line.cov)}, {"length", s.length_m()}};
}

}  // namespace

world::Observation parse_primitives(std::string_view body, const world::WorldOptions& options, const PrimitiveLimits& limits) {
  json doc;
  try {
    doc = json::parse(body.begin(), body.end());
  } catch (const json::parse_error& e) {
    throw api::bad_request("", std::string("malformed JSON: ") + e.what());
  } catch (const json::out_of_range& e) {
    // nlohmann refuses literals like 1e999 that overflow a double: they would become Inf.
    throw api::bad_request("", std::string("number out of range (must be finite): ") + e.what());
  }
  if (!doc.is_object()) throw api::bad_request("", "expected an object with \"segments\"");
  for (const auto& [key, value] : doc.items())
    if (key != "source" && key != "stamp" && key != "segments" && key != "sensor")
      throw api::bad_request(key, "unknown field");
  world::Observation observation;
  observation.observer = "anonymous";
  if (auto it = doc.find("source"); it != doc.end()) {
    if (!it->is_string() || it->get<std::string>().empty() || it->get<std::string>().size() > 128)
      throw api::bad_request("source", "expected a non-empty string of at most 128 characters");
    observation.observer = it->get<std::string>();
  }
  if (auto it = doc.find("sensor"); it != doc.end()) {
    // An atom the rules compare against (observation_sensor/1), e.g. laser or sonar.
    static const std::regex kSensor("[a-z][a-z0-9_]{0,31}");
    if (!it->is_string() || !std::regex_match(it->get<std::string>(), kSensor))
      throw api::bad_request("sensor", "expected a lower-case name like \"laser\" or \"sonar\"");
    observation.sensor = it->get<std::string>();
  }
  if (auto it = doc.find("stamp"); it != doc.end()) observation.stamp_s = finite_number(*it, "stamp", 1e12);
  auto it = doc.find("segments");
  if (it == doc.end()) throw api::bad_request("segments", "missing field");
  if (!it->is_array()) throw api::bad_request("segments", "expected an array");
  if (it->empty()) throw api::bad_request("segments", "must not be empty");
  if (it->size() > limits.max_segments)
    throw api::bad_request("segments", "more than " + std::to_string(limits.max_segments) + " segments in one request");
  for (std::size_t i = 0; i < it->size(); ++i) {
    const auto path = item("segments", i);
    const json& s = (*it)[i];
    if (!s.is_object()) throw api::bad_request(path, "expected {\"p0\", \"p1\", \"cov\"?}");
    for (const auto& [key, value] : s.items())
      if (key != "p0" && key != "p1" && key != "cov") throw api::bad_request(field(path, key), "unknown field");
    if (!s.contains("p0")) throw api::bad_request(field(path, "p0"), "missing field");
    if (!s.contains("p1")) throw api::bad_request(field(path, "p1"), "missing field");
    const auto p0 = point(s["p0"], field(path, "p0"), limits.max_abs_coordinate_m);
    const auto p1 = point(s["p1"], field(path, "p1"), limits.max_abs_coordinate_m);
    if ((p1 - p0).norm() < limits.min_length_m)
      throw api::bad_request(path, "segment shorter than " + std::to_string(limits.min_length_m) + " m");
    try {
      if (s.contains("cov")) {
        observation.segments.push_back({fusion::LineSegment::from_points(p0, p1, covariance(s["cov"], field(path, "cov")))});
      } else {
        auto segment = fusion::LineSegment::from_points(p0, p1, Eigen::Matrix2d::Identity());
        segment.line.cov = world::midpoint_line_cov(segment, options.default_offset_sigma_m, options.default_angle_sigma_rad);
        observation.segments.push_back({segment});
      }
    } catch (const std::invalid_argument& e) {
      throw api::bad_request(path, e.what());
    }
  }
  return observation;
}

json object_json(const world::ObjectState& object, const world::WorldOptions& options) {
  const auto& plan = *object.plan;
  const auto& pose = object.body.pose();
  json edges = json::array();
  for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
    json e = segment_json(world::apriori_edge(object, k, options));
    e["id"] = world::edge_id(plan.id, k);
    edges.push_back(std::move(e));
  }
  return {{"id", plan.id},
          {"kind", plan.kind},
          {"attributes", plan.attributes},
          {"pose", {{"x", pose.x_m}, {"y", pose.y_m}, {"theta", pose.theta_rad}}},
          {"pose_cov", matrix_json(object.body.pose_cov())},
          {"drawn_pose", {{"x", plan.pose.x_m}, {"y", plan.pose.y_m}, {"theta", plan.pose.theta_rad}}},
          {"confirmations", object.confirmations},
          {"adjustments", object.adjustments},
          {"updated_version", object.updated_version},
          {"edges", std::move(edges)}};
}

json element_json(const world::Element& element) {
  json j = segment_json(element.segment);
  j["id"] = element.id();
  j["support"] = element.support;
  j["source"] = element.source;
  j["observer"] = element.observer;
  j["created_version"] = element.created_version;
  j["updated_version"] = element.updated_version;
  return j;
}

json map_json(const world::WorldState& state, const world::WorldOptions& options) {
  json objects = json::array();
  for (const auto& o : state.objects) objects.push_back(object_json(o, options));
  json elements = json::array();
  for (const auto& [number, e] : state.elements) elements.push_back(element_json(e));
  return {{"version", state.version}, {"plan", state.plan_name}, {"objects", std::move(objects)}, {"elements", std::move(elements)}};
}

namespace {

json optional_text(const std::optional<std::string>& text) { return text ? json(*text) : json(nullptr); }

// The numbers a decision changed (see DecisionRecord::before), labelled.
json state_numbers_json(const std::string& action, const std::vector<double>& v) {
  if (v.size() == 6) {
    return {{"rho", v[0]}, {"phi", v[1]}, {"cov", json::array({json::array({v[2], v[3]}), json::array({v[4], v[5]})})}};
  }
  if (v.size() == 12) {
    json cov = json::array();
    for (int r = 0; r < 3; ++r) cov.push_back(json::array({v[3 + 3 * r], v[4 + 3 * r], v[5 + 3 * r]}));
    return {{"pose", {{"x", v[0]}, {"y", v[1]}, {"theta", v[2]}}}, {"pose_cov", cov}};
  }
  (void)action;
  return nullptr;
}

}  // namespace

json decision_json(const world::DecisionRecord& d) {
  json j = {{"seq", d.seq},
            {"observation", d.observation_seq},
            {"index", d.index},
            {"action", d.action},
            {"rule", d.rule},
            {"explanation", d.explanation},
            {"element", optional_text(d.element)},
            {"object", optional_text(d.object)},
            {"matched", {{"element", optional_text(d.matched_element)}, {"object", optional_text(d.matched_object)}}},
            {"mahalanobis_sq", d.mahalanobis_sq ? json(*d.mahalanobis_sq) : json(nullptr)},
            {"fallback", d.fallback},
            {"source", d.observer},
            {"origin", d.origin},
            {"sensor", d.sensor},
            {"observed",
             {{"p0", point_json(d.p0)}, {"p1", point_json(d.p1)}, {"rho", d.rho_m}, {"phi", d.phi_rad},
              {"cov", matrix_json(d.observed_cov)}}}};
  if (!d.before.empty()) j["before"] = state_numbers_json(d.action, d.before);
  if (!d.after.empty()) j["after"] = state_numbers_json(d.action, d.after);
  return j;
}

json decision_json(const rules::Decision& d) {
  return {{"action", d.action}, {"rule", d.rule}, {"explanation", d.explanation}, {"fallback", d.fallback}};
}

json rules_status_json(const rules::RulesStatus& status) {
  json files = json::array();
  for (const auto& f : status.files)
    files.push_back({{"path", f.path}, {"checksum", f.sha256_or_checksum}, {"loaded_at", f.loaded_at_unix_s}});
  return {{"files", files}, {"generation", status.generation}, {"last_error", status.last_error}};
}

namespace {

json query_value_json(const rules::QueryValue& v) {
  using Kind = rules::QueryValue::Kind;
  switch (v.kind) {
    case Kind::unbound: return nullptr;
    case Kind::atom:
    case Kind::string:
    case Kind::compound: return v.text;
    case Kind::integer: return v.integer;
    case Kind::floating: return std::isfinite(v.floating) ? json(v.floating) : json(nullptr);
    case Kind::list: {
      json items = json::array();
      for (const auto& item : v.items) items.push_back(query_value_json(item));
      return items;
    }
  }
  return nullptr;
}

}  // namespace

json query_result_json(const rules::QueryResult& result) {
  json solutions = json::array();
  for (const auto& row : result.solutions) {
    json solution = json::object();
    for (std::size_t i = 0; i < row.size() && i < result.variables.size(); ++i)
      solution[result.variables[i]] = query_value_json(row[i]);
    solutions.push_back(std::move(solution));
  }
  return {{"variables", result.variables}, {"solutions", solutions}, {"count", result.solutions.size()},
          {"truncated", result.truncated}};
}

}  // namespace wm::json_codec
