#include "server/world/changes.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

namespace wm::world {
namespace {

std::string centimetres(double metres) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f", metres);
  return text;
}

// The box around every edge of the plan as placed, grown by `margin`; nullopt without a plan or with no limit.
std::optional<Eigen::AlignedBox2d> plan_footprint(const WorldState& state, double margin) {
  if (margin < 0 || state.objects.empty()) return std::nullopt;
  Eigen::AlignedBox2d box;
  for (const auto& object : state.objects)
    for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
      const auto edge = object.body.world_edge(k, Eigen::Matrix2d::Zero());
      box.extend(edge.p0());
      box.extend(edge.p1());
    }
  if (box.isEmpty()) return std::nullopt;
  box.min().array() -= margin;
  box.max().array() += margin;
  return box;
}

}  // namespace

std::vector<Change> list_changes(const WorldState& state, const PlanReport* evidence, const ChangeOptions& options) {
  std::vector<Change> changes;
  if (evidence) {
    for (const auto& verdict : evidence->verdicts) {
      const auto index = state.objects.index_of(verdict.object_id);
      if (!index) continue;  // the plan changed since the verdict
      const ObjectState& object = state.objects[*index];
      Change change;
      change.object_id = verdict.object_id;
      change.rule = verdict.rule;
      change.explanation = verdict.explanation;
      if (!verdict.edge) {
        if (verdict.verdict != "gone") continue;  // a verdict the server does not know how to turn into a plan edit
        change.kind = ChangeKind::object_gone;
        change.key = "gone:" + verdict.object_id;
        double seen = 0, through = 0;
        for (std::size_t k = 0; k < object.body.edges().size(); ++k)
          if (const auto* e = evidence->find(*index, k)) {
            seen += e->observed * e->length_m;
            through += e->seen_through * e->length_m;
          }
        change.confidence = seen > 0 ? through / seen : 0;
        const auto& pose = object.body.pose();
        change.p0 = change.p1 = Eigen::Vector2d(pose.x_m, pose.y_m);
        changes.push_back(std::move(change));
        continue;
      }
      if (*verdict.edge >= object.body.edges().size()) continue;
      if (verdict.verdict != "missing" && verdict.verdict != "partly_missing") continue;
      const auto segment = object.body.world_edge(*verdict.edge, Eigen::Matrix2d::Zero());
      const std::string edge = edge_id(verdict.object_id, *verdict.edge);
      const double length = segment.length_m();
      const double s0 = std::clamp(verdict.stretch.s0_m, 0.0, length),
                   s1 = std::clamp(verdict.stretch.s1_m, s0, length);
      change.kind = verdict.verdict == "missing" ? ChangeKind::wall_missing : ChangeKind::wall_partly_missing;
      change.key = verdict.verdict == "missing"
                       ? "missing:" + edge
                       : "partly_missing:" + edge + "@" + centimetres(s0) + "-" + centimetres(s1);
      change.edge = verdict.edge;
      change.stretch = {s0, s1};
      const Eigen::Vector2d a = segment.p0(), b = segment.p1();
      change.p0 = a + (s0 / length) * (b - a);
      change.p1 = a + (s1 / length) * (b - a);
      change.length_m = s1 - s0;
      change.evidence = evidence->find(*index, *verdict.edge);
      if (change.evidence && change.evidence->observed > 0)
        change.confidence = std::min(1.0, change.evidence->seen_through / change.evidence->observed);
      changes.push_back(std::move(change));
    }
  }
  const auto report = as_built_report(state, evidence);
  for (const auto& entry : report.objects) {
    if (!entry.moved_by || entry.status == AsBuiltStatus::gone) continue;
    const auto& d = *entry.moved_by;
    const double sigma = std::max(d.sigma_xy_m, 1e-6);
    const double sigma_theta = std::sqrt(std::max(entry.object->body.pose_cov()(2, 2), 1e-12));
    const bool moved = (d.distance_m > options.min_move_m && d.distance_m > 2 * sigma) ||
                       (std::abs(d.dtheta_rad) > options.min_turn_rad && std::abs(d.dtheta_rad) > 2 * sigma_theta);
    if (!moved) continue;
    Change change;
    change.kind = ChangeKind::object_moved;
    change.object_id = entry.object->plan->id;
    change.key = "moved:" + change.object_id;
    change.moved_by = d;
    const auto& pose = entry.object->body.pose();
    change.p0 = Eigen::Vector2d(pose.x_m - d.dx_m, pose.y_m - d.dy_m);
    change.p1 = Eigen::Vector2d(pose.x_m, pose.y_m);
    change.length_m = d.distance_m;
    const double z2 = std::pow(d.distance_m / sigma, 2) + std::pow(d.dtheta_rad / sigma_theta, 2);
    change.confidence = 1.0 - std::exp(-z2 / 2);
    change.rule = "not_deformable_rigid";
    char text[256];
    std::snprintf(text, sizeof text,
                  "%s was adjusted %lld times: it stands %.3f m (dx %.3f, dy %.3f, ± %.3f m) and %.2f° from its "
                  "drawing",
                  change.object_id.c_str(), static_cast<long long>(entry.object->adjustments), d.distance_m, d.dx_m,
                  d.dy_m, d.sigma_xy_m, d.dtheta_rad * 180 / 3.14159265358979323846);
    change.explanation = text;
    changes.push_back(std::move(change));
  }
  const auto footprint = plan_footprint(state, options.plan_margin_m);
  for (const auto* element : report.not_in_plan) {
    const double length = element->segment.length_m();
    if (length < options.min_new_wall_length_m || element->support < options.min_new_wall_support) continue;
    if (footprint && !footprint->contains(element->segment.p0()) && !footprint->contains(element->segment.p1()))
      continue;  // beyond the building the plan draws
    Change change;
    change.kind = ChangeKind::new_wall;
    change.element_id = element->id();
    change.key = "new:" + change.element_id;
    change.p0 = element->segment.p0();
    change.p1 = element->segment.p1();
    change.length_m = length;
    change.support = element->support;
    change.confidence = std::min(1.0, static_cast<double>(element->support) / 10.0);
    change.rule = "not_in_plan";
    char text[256];
    std::snprintf(text, sizeof text,
                  "element %s (%.2f m, %lld observations, origin %s) belongs to no object of the plan: a wall the "
                  "plan does not have",
                  change.element_id.c_str(), length, static_cast<long long>(element->support), element->origin.c_str());
    change.explanation = text;
    changes.push_back(std::move(change));
  }
  for (auto& change : changes) change.id = change_id(change.key);
  return changes;
}

std::string change_id(const std::string& key) {
  // FNV-1a, 64 bits: no dependency, stable across builds and platforms.
  std::uint64_t hash = 14695981039346656037ull;
  for (const unsigned char c : key) {
    hash ^= c;
    hash *= 1099511628211ull;
  }
  char text[24];
  std::snprintf(text, sizeof text, "c%012llx", static_cast<unsigned long long>(hash >> 16));
  return text;
}

const char* to_string(ChangeKind kind) {
  switch (kind) {
    case ChangeKind::wall_missing:
      return "wall_missing";
    case ChangeKind::wall_partly_missing:
      return "wall_partly_missing";
    case ChangeKind::object_gone:
      return "object_gone";
    case ChangeKind::object_moved:
      return "object_moved";
    case ChangeKind::new_wall:
      return "new_wall";
  }
  return "new_wall";
}

}  // namespace wm::world
