#include "apriori/import/rmf_import.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include "apriori/internal/plan_builder.h"
#include "common/utf8.h"

namespace wm::apriori {
namespace {

using internal::WorldShape;

std::string index(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

double number(const YAML::Node& node, const std::string& path) {
  if (!node || !node.IsScalar()) throw FloorPlanError(path, "expected a number");
  double v = 0.0;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    throw FloorPlanError(path, "expected a number, got '" + node.Scalar() + "'");
  }
  if (!std::isfinite(v)) throw FloorPlanError(path, "not a finite number");
  return v;
}

/// traffic-editor parameters are written [type_code, value]; nullopt when `key` is absent or not of that form.
/// (A default-constructed YAML::Node is a defined null node, so "absent" needs the optional.)
std::optional<YAML::Node> param(const YAML::Node& params, const char* key) {
  if (!params || !params.IsMap()) return std::nullopt;
  const YAML::Node p = params[key];
  if (!p || !p.IsSequence() || p.size() != 2) return std::nullopt;
  return p[1];
}

struct Vertex {
  Eigen::Vector2d raw;  // as written (pixels, y down, or metres)
};

class RmfImporter {
 public:
  RmfImporter(const YAML::Node& root, const RmfImportOptions& options, ImportReport& report)
      : root_(root), options_(options), report_(report), builder_(options.name, options.limits) {}

  FloorPlan run() && {
    std::string system = "reference_image";
    if (const auto cs = root_["coordinate_system"]) {
      if (!cs.IsScalar()) throw FloorPlanError("coordinate_system", "expected a name");
      system = cs.Scalar();
    }
    if (system == "reference_image") {
      flip_ = -1.0;
    } else if (system == "cartesian_meters") {
      flip_ = 1.0;
    } else {
      throw FloorPlanError("coordinate_system",
                           "'" + system + "' is not supported (reference_image or cartesian_meters)");
    }
    const YAML::Node levels = root_["levels"];
    if (!levels || !levels.IsMap() || levels.size() == 0) throw FloorPlanError("levels", "no levels in the building");
    const auto [name, level] = choose_level(levels);
    if (const auto bad = common::invalid_utf8_offset(name))
      throw FloorPlanError("levels", "level name is not UTF-8 after unescaping (byte " + std::to_string(*bad) + ")");
    report_.version = name;
    const std::string path = "levels." + name;
    read_vertices(level["vertices"], path + ".vertices");
    if (system == "reference_image") {
      scale_from_measurements(level["measurements"], path + ".measurements");
    } else {
      scale_ = 1.0;
      report_.units_source = "cartesian_meters";
      if (options_.metres_per_pixel)
        report_.warnings.push_back("metres_per_pixel ignored: the map is in cartesian_meters");
    }
    report_.units_to_m = scale_;
    walls(level["walls"], path + ".walls");
    doors(level["doors"], path + ".doors");
    models(level["models"], path + ".models");
    for (const char* key : {"floors", "lanes", "measurements", "vertices"}) {
      const YAML::Node n = level[key];
      report_.entity_counts[key] = n && n.IsSequence() ? n.size() : 0;
    }
    report_.objects = builder_.size();
    report_.extent = builder_.extent();
    return std::move(builder_).finish();
  }

 private:
  std::pair<std::string, YAML::Node> choose_level(const YAML::Node& levels) {
    std::vector<std::pair<std::string, YAML::Node>> all;
    for (const auto& kv : levels) all.emplace_back(kv.first.Scalar(), kv.second);
    if (!options_.level.empty()) {
      for (const auto& [name, node] : all)
        if (name == options_.level) return {name, node};
      std::string names;
      for (const auto& l : all) names += (names.empty() ? "" : ", ") + l.first;
      throw FloorPlanError("levels", "no level '" + options_.level + "' (the building has " + names + ")");
    }
    std::size_t best = 0;
    double best_elevation = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < all.size(); ++i) {
      const YAML::Node e = all[i].second["elevation"];
      const double elevation = e ? number(e, "levels." + all[i].first + ".elevation") : 0.0;
      if (elevation < best_elevation) {
        best_elevation = elevation;
        best = i;
      }
    }
    if (all.size() > 1)
      report_.warnings.push_back("the building has " + std::to_string(all.size()) + " levels; imported '" +
                                 all[best].first + "' (the lowest); choose another with the level option");
    return all[best];
  }

  void read_vertices(const YAML::Node& node, const std::string& path) {
    if (!node) return;
    if (!node.IsSequence()) throw FloorPlanError(path, "expected a list of [x, y, z, name]");
    for (std::size_t i = 0; i < node.size(); ++i) {
      const auto v = node[i];
      const auto vpath = index(path, i);
      if (!v.IsSequence() || v.size() < 2) throw FloorPlanError(vpath, "expected [x, y, z, name]");
      vertices_.push_back({{number(v[0], index(vpath, 0)), number(v[1], index(vpath, 1))}});
    }
  }

  Eigen::Vector2d world(const Eigen::Vector2d& raw) const { return {raw.x() * scale_, flip_ * raw.y() * scale_}; }

  const Vertex& vertex(const YAML::Node& n, const std::string& path) const {
    if (!n || !n.IsScalar()) throw FloorPlanError(path, "expected a vertex index");
    long long i = -1;
    try {
      i = n.as<long long>();
    } catch (const YAML::Exception&) {
      throw FloorPlanError(path, "expected a vertex index, got '" + n.Scalar() + "'");
    }
    if (i < 0 || static_cast<std::size_t>(i) >= vertices_.size())
      throw FloorPlanError(path, "vertex index " + std::to_string(i) + " out of range (" +
                                     std::to_string(vertices_.size()) + " vertices)");
    return vertices_[static_cast<std::size_t>(i)];
  }

  void scale_from_measurements(const YAML::Node& node, const std::string& path) {
    if (options_.metres_per_pixel) {
      scale_ = *options_.metres_per_pixel;
      report_.units_source = "override";
      return;
    }
    if (!node || !node.IsSequence() || node.size() == 0)
      throw FloorPlanError(path, "the level has no measurements, so its scale is unknown: give metres_per_pixel");
    double sum = 0.0;
    for (std::size_t i = 0; i < node.size(); ++i) {
      const auto m = node[i];
      const auto mpath = index(path, i);
      if (!m.IsSequence() || m.size() < 3) throw FloorPlanError(mpath, "expected [v0, v1, {distance: [3, d]}]");
      const double pixels = (vertex(m[0], index(mpath, 0)).raw - vertex(m[1], index(mpath, 1)).raw).norm();
      const auto d = param(m[2], "distance");
      if (!d) throw FloorPlanError(mpath, "missing distance");
      const double metres = number(*d, mpath + ".distance");
      if (!(pixels > 0.0) || !(metres > 0.0))
        throw FloorPlanError(mpath, "a measurement needs two distinct vertices and a distance > 0");
      sum += metres / pixels;
    }
    scale_ = sum / static_cast<double>(node.size());
    report_.units_source = "measurements (" + std::to_string(node.size()) + ")";
  }

  LayerReport& layer(const char* name, std::size_t entities) {
    auto& l = report_.layers[name];
    l.entities = entities;
    l.status = "mapped";
    return l;
  }

  void walls(const YAML::Node& node, const std::string& path) {
    if (!node) return;
    if (!node.IsSequence()) throw FloorPlanError(path, "expected a list of walls");
    auto& l = layer("walls", node.size());
    report_.entity_counts["walls"] = node.size();
    for (std::size_t i = 0; i < node.size(); ++i) {
      const auto w = node[i];
      const auto wpath = index(path, i);
      if (!w.IsSequence() || w.size() < 2) throw FloorPlanError(wpath, "expected [v0, v1, {params}]");
      WorldShape s;
      s.points = {world(vertex(w[0], index(wpath, 0)).raw), world(vertex(w[1], index(wpath, 1)).raw)};
      auto attributes = options_.wall_attributes;
      // traffic-editor draws glass partitions as translucent walls (alpha < 1).
      if (w.size() > 2)
        if (const auto alpha = param(w[2], "alpha");
            alpha && number(*alpha, wpath + ".alpha") < 1.0 &&
            std::find(attributes.begin(), attributes.end(), "glass") == attributes.end())
          attributes.push_back("glass");
      if (builder_.add("wall-" + std::to_string(i), "wall", attributes, {s}, std::nullopt, wpath)) {
        ++l.objects;
      } else {
        ++report_.skipped["degenerate wall"];
      }
    }
  }

  void doors(const YAML::Node& node, const std::string& path) {
    if (!node) return;
    if (!node.IsSequence()) throw FloorPlanError(path, "expected a list of doors");
    auto& l = layer("doors", node.size());
    report_.entity_counts["doors"] = node.size();
    for (std::size_t i = 0; i < node.size(); ++i) {
      const auto d = node[i];
      const auto dpath = index(path, i);
      if (!d.IsSequence() || d.size() < 2) throw FloorPlanError(dpath, "expected [v0, v1, {params}]");
      WorldShape s;
      s.points = {world(vertex(d[0], index(dpath, 0)).raw), world(vertex(d[1], index(dpath, 1)).raw)};
      std::string id = "door-" + std::to_string(i);
      if (d.size() > 2)
        if (const auto name = param(d[2], "name"); name && name->IsScalar() && !name->Scalar().empty())
          id = "door-" + name->Scalar();
      if (builder_.add(id, "door", options_.door_attributes, {s}, std::nullopt, dpath)) {
        ++l.objects;
      } else {
        ++report_.skipped["degenerate door"];
      }
    }
  }

  void models(const YAML::Node& node, const std::string& path) {
    if (!node) return;
    if (!node.IsSequence()) throw FloorPlanError(path, "expected a list of models");
    auto& l = layer("models", node.size());
    report_.entity_counts["models"] = node.size();
    for (std::size_t i = 0; i < node.size(); ++i) {
      const auto m = node[i];
      const auto mpath = index(path, i);
      if (!m.IsMap()) throw FloorPlanError(mpath, "expected {model_name, name, x, y, yaw, static}");
      const std::string model_name = m["model_name"] && m["model_name"].IsScalar() ? m["model_name"].Scalar() : "";
      const std::string name = m["name"] && m["name"].IsScalar() ? m["name"].Scalar() : model_name;
      if (const auto st = m["static"]; st && st.IsScalar() && (st.Scalar() == "false" || st.Scalar() == "False")) {
        ++report_.skipped["model (not static)"];
        continue;
      }
      const LayerRule* rule = nullptr;
      for (const auto& r : options_.model_rules)
        if (glob_match(r.pattern, model_name)) {
          rule = &r;
          break;
        }
      if (rule && rule->ignore) {
        ++report_.skipped["model (ignored)"];
        continue;
      }
      const std::string kind = rule ? rule->kind : "furniture";
      const std::vector<std::string> attributes = rule ? rule->attributes : std::vector<std::string>{"not_deformable"};
      Eigen::Vector2d size = options_.default_model_size_m;
      for (const auto& [pattern, s] : options_.model_sizes)
        if (glob_match(pattern, model_name)) {
          size = s;
          break;
        }
      const Eigen::Vector2d p = world({number(m["x"], mpath + ".x"), number(m["y"], mpath + ".y")});
      const double yaw = m["yaw"] ? number(m["yaw"], mpath + ".yaw") : 0.0;
      const fusion::Pose2D pose{p.x(), p.y(), yaw};
      WorldShape s;
      s.closed = true;
      for (const auto& c : {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(0.5, -0.5), Eigen::Vector2d(0.5, 0.5),
                            Eigen::Vector2d(-0.5, 0.5)})
        s.points.push_back(pose.transform_point(c.cwiseProduct(size)));
      if (builder_.add(name.empty() ? "model-" + std::to_string(i) : name, kind, attributes, {s}, pose, mpath)) {
        ++l.objects;
      } else {
        ++report_.skipped["degenerate model"];
      }
    }
  }

  const YAML::Node& root_;
  const RmfImportOptions& options_;
  ImportReport& report_;
  internal::PlanBuilder builder_;
  std::vector<Vertex> vertices_;
  double scale_ = 1.0;
  double flip_ = -1.0;
};

}  // namespace

std::vector<std::string> rmf_level_names(std::string_view yaml_text) {
  if (const auto bad = common::invalid_utf8_offset(yaml_text)) {
    const auto line = 1 + std::count(yaml_text.begin(), yaml_text.begin() + static_cast<std::ptrdiff_t>(*bad), '\n');
    throw FloorPlanError("line " + std::to_string(line), "not UTF-8 (byte " + std::to_string(*bad) + ")");
  }
  try {
    const YAML::Node root = YAML::Load(std::string(yaml_text));
    const YAML::Node levels = root.IsMap() ? root["levels"] : YAML::Node();
    if (!levels || !levels.IsMap() || levels.size() == 0) throw FloorPlanError("levels", "no levels in the building");
    std::vector<std::pair<double, std::string>> by_elevation;
    for (const auto& kv : levels) {
      const auto name = kv.first.Scalar();
      const auto elevation = kv.second.IsMap() ? kv.second["elevation"] : YAML::Node();
      double height = 0;
      if (elevation && !YAML::convert<double>::decode(elevation, height))
        throw FloorPlanError("levels." + name + ".elevation", "not a number");
      by_elevation.emplace_back(height, name);
    }
    std::stable_sort(by_elevation.begin(), by_elevation.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<std::string> names;
    for (auto& [height, name] : by_elevation) names.push_back(std::move(name));
    return names;
  } catch (const YAML::Exception& e) {
    throw FloorPlanError(e.mark.is_null() ? std::string() : "line " + std::to_string(e.mark.line + 1),
                         "malformed YAML: " + e.msg);
  }
}

ImportResult import_rmf_building(std::string_view yaml_text, const RmfImportOptions& options) {
  if (options.metres_per_pixel && !(std::isfinite(*options.metres_per_pixel) && *options.metres_per_pixel > 0.0))
    throw std::invalid_argument("import_rmf_building: metres_per_pixel must be finite and > 0");
  auto valid_size = [](const Eigen::Vector2d& s) { return s.allFinite() && s.x() > 0.0 && s.y() > 0.0; };
  if (!valid_size(options.default_model_size_m))
    throw std::invalid_argument("import_rmf_building: default_model_size_m must be finite and > 0");
  for (const auto& [pattern, size] : options.model_sizes)
    if (!valid_size(size))
      throw std::invalid_argument("import_rmf_building: model size for '" + pattern + "' must be > 0");
  // YAML is Unicode text, and names end up in the plan's JSON: bytes that are not UTF-8 are refused here,
  // with where, rather than by the JSON writer later.
  if (const auto bad = common::invalid_utf8_offset(yaml_text)) {
    const auto line = 1 + std::count(yaml_text.begin(), yaml_text.begin() + static_cast<std::ptrdiff_t>(*bad), '\n');
    throw FloorPlanError("line " + std::to_string(line), "not UTF-8 (byte " + std::to_string(*bad) + ")");
  }
  ImportResult result;
  result.report.format = "rmf-building";
  try {
    const YAML::Node root = YAML::Load(std::string(yaml_text));
    if (!root.IsMap()) throw FloorPlanError("", "a building.yaml is a YAML map with \"levels\"");
    result.plan = RmfImporter(root, options, result.report).run();
  } catch (const YAML::Exception& e) {
    throw FloorPlanError(e.mark.is_null() ? std::string() : "line " + std::to_string(e.mark.line + 1),
                         "malformed YAML: " + e.msg);
  }
  return result;
}

}  // namespace wm::apriori
