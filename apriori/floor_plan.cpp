#include "apriori/floor_plan.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>

#include "apriori/import/json_limits.h"

namespace wm::apriori {
namespace {

using nlohmann::json;

std::string join(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string index(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

void require_known_keys(const json& object, const std::string& path, std::initializer_list<const char*> known) {
  for (const auto& [key, value] : object.items()) {
    const bool ok = std::any_of(known.begin(), known.end(), [&key = key](const char* k) { return key == k; });
    if (!ok) throw FloorPlanError(join(path, key), "unknown field");
  }
}

const json& require(const json& object, const std::string& path, const char* key) {
  auto it = object.find(key);
  if (it == object.end()) throw FloorPlanError(join(path, key), "missing field");
  return *it;
}

double number(const json& value, const std::string& path, double limit) {
  if (!value.is_number()) throw FloorPlanError(path, "expected a number");
  const double v = value.get<double>();
  if (!std::isfinite(v)) throw FloorPlanError(path, "not a finite number");
  if (std::abs(v) > limit) throw FloorPlanError(path, "absurd value (|v| > " + std::to_string(limit) + ")");
  return v;
}

std::string text(const json& value, const std::string& path, std::size_t max_length) {
  if (!value.is_string()) throw FloorPlanError(path, "expected a string");
  auto s = value.get<std::string>();
  if (s.empty()) throw FloorPlanError(path, "must not be empty");
  if (s.size() > max_length) throw FloorPlanError(path, "longer than " + std::to_string(max_length) + " characters");
  if (std::any_of(s.begin(), s.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; }))
    throw FloorPlanError(path, "control characters are not allowed");
  return s;
}

// Attributes become Prolog atoms in rules; a lower-case identifier keeps rule files readable (solid, glass).
std::string attribute(const json& value, const std::string& path) {
  auto s = text(value, path, 64);
  const bool ok =
      std::islower(static_cast<unsigned char>(s[0])) &&
      std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::islower(c) || std::isdigit(c) || c == '_'; });
  if (!ok) throw FloorPlanError(path, "attribute must match [a-z][a-z0-9_]*, got '" + s + "'");
  return s;
}

Eigen::Vector2d point(const json& value, const std::string& path, double scale, double limit) {
  if (!value.is_array() || value.size() != 2) throw FloorPlanError(path, "expected a point [x, y]");
  return {number(value[0], index(path, 0), limit / scale) * scale,
          number(value[1], index(path, 1), limit / scale) * scale};
}

std::vector<Eigen::Vector2d> points(const json& value, const std::string& path, double scale,
                                    const FloorPlanLimits& limits, std::size_t min_count) {
  if (!value.is_array()) throw FloorPlanError(path, "expected an array of points");
  if (value.size() < min_count) throw FloorPlanError(path, "needs at least " + std::to_string(min_count) + " points");
  if (value.size() > limits.max_points_per_object) throw FloorPlanError(path, "too many points");
  std::vector<Eigen::Vector2d> result;
  result.reserve(value.size());
  for (std::size_t i = 0; i < value.size(); ++i) {
    result.push_back(point(value[i], index(path, i), scale, limits.max_abs_coordinate_m));
    if (i > 0 && (result[i] - result[i - 1]).norm() < 1e-6)
      throw FloorPlanError(index(path, i), "repeats the previous point (zero-length edge)");
  }
  return result;
}

Eigen::Matrix3d covariance(const json& value, const std::string& path) {
  if (!value.is_array() || value.size() != 3) throw FloorPlanError(path, "expected a 3x3 matrix");
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r) {
    const auto row_path = index(path, r);
    if (!value[r].is_array() || value[r].size() != 3) throw FloorPlanError(row_path, "expected 3 numbers");
    for (int c = 0; c < 3; ++c) m(r, c) = number(value[r][c], index(row_path, c), 1e6);
  }
  if (!m.isApprox(m.transpose(), 1e-12) && (m - m.transpose()).norm() > 1e-15)
    throw FloorPlanError(path, "not symmetric");
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m);
  if (eig.eigenvalues().minCoeff() <= 0.0) throw FloorPlanError(path, "not positive definite");
  return m;
}

double unit_scale(const json& doc) {
  auto it = doc.find("units");
  if (it == doc.end()) return 1.0;
  if (!it->is_string()) throw FloorPlanError("units", "expected \"m\", \"cm\" or \"mm\"");
  const auto u = it->get<std::string>();
  if (u == "m") return 1.0;
  if (u == "cm") return 0.01;
  if (u == "mm") return 0.001;
  throw FloorPlanError("units", "unknown unit '" + u + "' (expected \"m\", \"cm\" or \"mm\")");
}

PlanObject parse_object(const json& value, const std::string& path, double scale, const FloorPlanLimits& limits) {
  if (!value.is_object()) throw FloorPlanError(path, "expected an object");
  require_known_keys(value, path,
                     {"id", "kind", "attributes", "pose", "pose_cov", "segments", "polygon", "description"});
  PlanObject object;
  object.id = text(require(value, path, "id"), join(path, "id"), limits.max_id_length);
  if (object.id.find('/') != std::string::npos)
    throw FloorPlanError(join(path, "id"), "'/' is reserved for edge ids (object/k)");
  object.kind = text(require(value, path, "kind"), join(path, "kind"), limits.max_id_length);
  if (auto it = value.find("attributes"); it != value.end()) {
    const auto apath = join(path, "attributes");
    if (!it->is_array()) throw FloorPlanError(apath, "expected an array of attribute names");
    for (std::size_t i = 0; i < it->size(); ++i) {
      auto a = attribute((*it)[i], index(apath, i));
      if (!object.has_attribute(a)) object.attributes.push_back(std::move(a));
    }
  }
  if (auto it = value.find("pose"); it != value.end()) {
    const auto ppath = join(path, "pose");
    if (!it->is_object()) throw FloorPlanError(ppath, "expected {\"x\", \"y\", \"theta\"}");
    require_known_keys(*it, ppath, {"x", "y", "theta"});
    object.pose.x_m = number(require(*it, ppath, "x"), join(ppath, "x"), limits.max_abs_coordinate_m / scale) * scale;
    object.pose.y_m = number(require(*it, ppath, "y"), join(ppath, "y"), limits.max_abs_coordinate_m / scale) * scale;
    object.pose.theta_rad = number(require(*it, ppath, "theta"), join(ppath, "theta"), 1e3);
  }
  if (auto it = value.find("pose_cov"); it != value.end()) object.pose_cov = covariance(*it, join(path, "pose_cov"));
  if (auto it = value.find("segments"); it != value.end()) {
    const auto spath = join(path, "segments");
    if (!it->is_array()) throw FloorPlanError(spath, "expected an array of polylines");
    for (std::size_t i = 0; i < it->size(); ++i)
      object.polylines.push_back(points((*it)[i], index(spath, i), scale, limits, 2));
  }
  if (auto it = value.find("polygon"); it != value.end()) {
    object.polygon = points(*it, join(path, "polygon"), scale, limits, 3);
    if ((object.polygon.front() - object.polygon.back()).norm() < 1e-6)
      throw FloorPlanError(join(path, "polygon"), "do not repeat the first point: polygons are closed implicitly");
  }
  if (object.polylines.empty() && object.polygon.empty())
    throw FloorPlanError(path, "needs \"segments\" or \"polygon\"");
  return object;
}

json point_json(const Eigen::Vector2d& p) { return json::array({p.x(), p.y()}); }

}  // namespace

bool PlanObject::has_attribute(std::string_view a) const {
  return std::find(attributes.begin(), attributes.end(), a) != attributes.end();
}

std::vector<fusion::LocalEdge> PlanObject::edges() const {
  std::vector<fusion::LocalEdge> result;
  for (const auto& line : polylines)
    for (std::size_t i = 0; i + 1 < line.size(); ++i) result.push_back({line[i], line[i + 1]});
  for (std::size_t i = 0; i < polygon.size(); ++i) result.push_back({polygon[i], polygon[(i + 1) % polygon.size()]});
  return result;
}

FloorPlan parse_floor_plan_json(std::string_view text_in, const FloorPlanLimits& limits) {
  if (auto error = json_nesting_error(text_in)) throw FloorPlanError("", *error);
  json doc;
  try {
    doc = json::parse(text_in.begin(), text_in.end());
  } catch (const json::parse_error& e) {
    throw FloorPlanError("", std::string("malformed JSON: ") + e.what());
  } catch (const json::out_of_range& e) {
    // nlohmann refuses literals like 1e999 that overflow a double: they would become Inf.
    throw FloorPlanError("", std::string("number out of range (must be finite): ") + e.what());
  }
  if (!doc.is_object()) throw FloorPlanError("", "a floor plan is a JSON object with \"objects\"");
  // "placement" and "georeference" are what GET /api/v1/floorplan adds: a plan read back loads as it was drawn
  // (the placement in force stays; it changes only through its own requests).
  require_known_keys(doc, "", {"name", "units", "objects", "description", "placement", "georeference"});
  FloorPlan plan;
  plan.name = doc.contains("name") ? text(doc["name"], "name", 256) : std::string("unnamed");
  const double scale = unit_scale(doc);
  const json& objects = require(doc, "", "objects");
  if (!objects.is_array()) throw FloorPlanError("objects", "expected an array");
  if (objects.size() > limits.max_objects) throw FloorPlanError("objects", "too many objects");
  std::set<std::string> ids;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    auto object = parse_object(objects[i], index("objects", i), scale, limits);
    if (!ids.insert(object.id).second)
      throw FloorPlanError(index("objects", i) + ".id", "duplicate id '" + object.id + "'");
    plan.objects.push_back(std::move(object));
  }
  return plan;
}

std::string to_json_text(const FloorPlan& plan) {
  json objects = json::array();
  for (const auto& o : plan.objects) {
    json j = {{"id", o.id},
              {"kind", o.kind},
              {"attributes", o.attributes},
              {"pose", {{"x", o.pose.x_m}, {"y", o.pose.y_m}, {"theta", o.pose.theta_rad}}}};
    if (o.pose_cov) {
      json rows = json::array();
      for (int r = 0; r < 3; ++r) rows.push_back({(*o.pose_cov)(r, 0), (*o.pose_cov)(r, 1), (*o.pose_cov)(r, 2)});
      j["pose_cov"] = rows;
    }
    if (!o.polylines.empty()) {
      json lines = json::array();
      for (const auto& line : o.polylines) {
        json pts = json::array();
        for (const auto& p : line) pts.push_back(point_json(p));
        lines.push_back(pts);
      }
      j["segments"] = lines;
    }
    if (!o.polygon.empty()) {
      json pts = json::array();
      for (const auto& p : o.polygon) pts.push_back(point_json(p));
      j["polygon"] = pts;
    }
    objects.push_back(std::move(j));
  }
  return json{{"name", plan.name}, {"units", "m"}, {"objects", objects}}.dump();
}

}  // namespace wm::apriori
