#include "apriori/internal/plan_builder.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "common/utf8.h"

namespace wm::apriori::internal {
namespace {

// parse_floor_plan_json rejects an edge shorter than this [m]; the builder drops such points instead.
constexpr double kMinEdgeM = 1e-6;

std::string format_number(double v) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

/// Points in the object frame, without near-duplicates; nullopt when fewer than two distinct points remain.
std::optional<std::vector<Eigen::Vector2d>> clean(const WorldShape& shape, const fusion::Pose2D& pose) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(shape.points.size() + 1);
  for (const auto& w : shape.points) {
    Eigen::Vector2d local =
        pose.theta_rad == 0.0 ? Eigen::Vector2d(w.x() - pose.x_m, w.y() - pose.y_m) : pose.inverse_transform_point(w);
    if (!out.empty() && (local - out.back()).norm() < kMinEdgeM) continue;
    out.push_back(local);
  }
  if (shape.closed)
    while (out.size() > 1 && (out.back() - out.front()).norm() < kMinEdgeM) out.pop_back();
  if (out.size() < 2) return std::nullopt;
  return out;
}

}  // namespace

void check_world_point(const Eigen::Vector2d& p, double limit_m, const std::string& where) {
  if (!std::isfinite(p.x()) || !std::isfinite(p.y())) throw FloorPlanError(where, "coordinate is not a finite number");
  if (std::abs(p.x()) > limit_m || std::abs(p.y()) > limit_m)
    throw FloorPlanError(where, "absurd coordinate (" + format_number(p.x()) + ", " + format_number(p.y()) +
                                    ") m: beyond ±" + format_number(limit_m) +
                                    " m (wrong units? set the unit override)");
}

Eigen::Vector2d centroid(const std::vector<WorldShape>& shapes) {
  Eigen::Vector2d weighted = Eigen::Vector2d::Zero();
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  double length = 0.0;
  std::size_t count = 0;
  for (const auto& s : shapes) {
    const std::size_t n = s.points.size();
    for (std::size_t i = 0; i < n; ++i) {
      sum += s.points[i];
      ++count;
      if (i + 1 < n || (s.closed && n > 2)) {
        const auto& a = s.points[i];
        const auto& b = s.points[(i + 1) % n];
        const double l = (b - a).norm();
        weighted += l * 0.5 * (a + b);
        length += l;
      }
    }
  }
  if (count == 0) throw std::invalid_argument("centroid: no points");
  return length > 1e-12 ? Eigen::Vector2d(weighted / length) : Eigen::Vector2d(sum / static_cast<double>(count));
}

PlanBuilder::PlanBuilder(std::string name, const FloorPlanLimits& limits) : limits_(limits) {
  plan_.name = std::move(name);
}

std::string PlanBuilder::unique_id(const std::string& hint) {
  std::string base;
  for (unsigned char c : hint) base += (c < 0x20 || c == 0x7f || c == '/' || c == ' ') ? '_' : static_cast<char>(c);
  if (base.empty()) base = "object";
  const std::size_t room = limits_.max_id_length > 12 ? limits_.max_id_length - 12 : limits_.max_id_length;
  if (base.size() > room) {
    base.resize(room);
    while (!base.empty() && (static_cast<unsigned char>(base.back()) & 0xC0) == 0x80) base.pop_back();  // UTF-8
    if (!base.empty() && static_cast<unsigned char>(base.back()) >= 0xC0) base.pop_back();
  }
  std::string id = base;
  for (std::size_t k = 2; ids_.count(id); ++k) id = base + "-" + std::to_string(k);
  ids_.insert(id);
  return id;
}

std::optional<std::string> PlanBuilder::add(const std::string& id_hint, const std::string& kind,
                                            const std::vector<std::string>& attributes,
                                            const std::vector<WorldShape>& shapes,
                                            const std::optional<fusion::Pose2D>& pose, const std::string& where) {
  bool any_point = false;
  for (const auto& s : shapes) {
    for (const auto& p : s.points) check_world_point(p, limits_.max_abs_coordinate_m, where);
    any_point = any_point || !s.points.empty();
  }
  if (!any_point) return std::nullopt;
  PlanObject object;
  object.kind = kind;
  object.attributes = attributes;
  if (pose) {
    object.pose = *pose;
  } else {
    const auto c = centroid(shapes);
    object.pose = {c.x(), c.y(), 0.0};
  }
  std::vector<std::pair<std::vector<Eigen::Vector2d>, bool>> cleaned;
  for (const auto& s : shapes) {
    if (auto pts = clean(s, object.pose)) {
      const bool closed = s.closed && pts->size() >= 3;
      cleaned.emplace_back(std::move(*pts), closed);
    }
  }
  if (cleaned.empty()) return std::nullopt;
  if (cleaned.size() == 1 && cleaned[0].second) {
    object.polygon = std::move(cleaned[0].first);
  } else {
    for (auto& [pts, closed] : cleaned) {
      if (closed) pts.push_back(pts.front());
      object.polylines.push_back(std::move(pts));
    }
  }
  auto too_many = [&](std::size_t n) {
    if (n > limits_.max_points_per_object)
      throw FloorPlanError(where, "too many points in one outline (" + std::to_string(n) + " > " +
                                      std::to_string(limits_.max_points_per_object) + ")");
  };
  too_many(object.polygon.size());
  for (const auto& line : object.polylines) too_many(line.size());
  if (plan_.objects.size() >= limits_.max_objects)
    throw FloorPlanError(where, "too many objects (more than " + std::to_string(limits_.max_objects) + ")");
  for (const auto& s : shapes) {
    for (const auto& p : s.points) {
      if (!extent_) extent_ = Extent{p, p};
      extent_->min_m = extent_->min_m.cwiseMin(p);
      extent_->max_m = extent_->max_m.cwiseMax(p);
    }
  }
  object.id = unique_id(id_hint);
  plan_.objects.push_back(std::move(object));
  return plan_.objects.back().id;
}

FloorPlan PlanBuilder::finish() && {
  // A parser may unescape text into bytes that are not UTF-8 (yaml-cpp turns some inputs into a lone 0xA0):
  // refused here, with the object named, rather than failing later when the plan is written as JSON.
  const auto require_utf8 = [](const std::string& text, const std::string& where) {
    if (const auto bad = common::invalid_utf8_offset(text))
      throw FloorPlanError(where, "not UTF-8 after unescaping (byte " + std::to_string(*bad) + ")");
  };
  require_utf8(plan_.name, "name");
  for (const auto& object : plan_.objects) {
    require_utf8(object.id, "object id");
    require_utf8(object.kind, "object " + object.id + " kind");
    for (const auto& attribute : object.attributes) require_utf8(attribute, "object " + object.id + " attribute");
  }
  try {
    parse_floor_plan_json(to_json_text(plan_), limits_);
  } catch (const FloorPlanError& e) {
    // The path starts "objects[i]": name the object instead of its index.
    const auto& path = e.path();
    std::string where = path;
    if (path.rfind("objects[", 0) == 0) {
      const auto close = path.find(']');
      const auto index = std::stoul(path.substr(8, close - 8));
      if (index < plan_.objects.size()) where = "object " + plan_.objects[index].id + path.substr(close + 1);
    }
    const std::string what = e.what();
    throw FloorPlanError(where, path.empty() ? what : what.substr(path.size() + 2));
  }
  return std::move(plan_);
}

}  // namespace wm::apriori::internal
