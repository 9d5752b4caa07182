#include "apriori/import/dxf_import.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>

#include "apriori/dxf/dxf_reader.h"
#include "apriori/internal/clustering.h"
#include "apriori/internal/plan_builder.h"

namespace wm::apriori {
namespace {

using internal::WorldShape;

constexpr double kPi = 3.14159265358979323846;
constexpr std::size_t kMaxNesting = 64;        // deeper block nesting is a corrupt or hostile file
constexpr std::size_t kMaxArcSegments = 4096;  // per arc; the report warns when the tolerance is not met
constexpr std::size_t kMaxInsertExpansions = 1'000'000;

/// OCS → WCS rotation for extrusion direction n (unit): the "arbitrary axis algorithm" of the DXF Reference.
Eigen::Matrix3d ocs_to_wcs(const Eigen::Vector3d& n) {
  if (n.x() == 0.0 && n.y() == 0.0 && n.z() > 0.0) return Eigen::Matrix3d::Identity();
  const bool near_z = std::abs(n.x()) < 1.0 / 64.0 && std::abs(n.y()) < 1.0 / 64.0;
  const Eigen::Vector3d ax =
      (near_z ? Eigen::Vector3d::UnitY().cross(n) : Eigen::Vector3d::UnitZ().cross(n)).normalized();
  const Eigen::Vector3d ay = n.cross(ax).normalized();
  Eigen::Matrix3d m;
  m.col(0) = ax;
  m.col(1) = ay;
  m.col(2) = n;
  return m;
}

/// How a block (or model space) maps into the world.
struct Frame {
  Eigen::Affine3d to_world = Eigen::Affine3d::Identity();  // block coordinates → world [m]
  std::string layer;                                       // inherited by entities on layer "0"; empty in model space
  std::string id;                  // handle chain of the enclosing INSERTs, each followed by '.'
  std::string where;               // error path prefix, e.g. "entity INSERT handle 2A > "
  std::vector<std::string> stack;  // upper-case names of the blocks being expanded
};

std::string entity_key(const dxf::Entity& e) { return e.handle.empty() ? "L" + std::to_string(e.line) : e.handle; }

/// Entities → polylines in the world, arcs replaced by chords.
class Tessellator {
 public:
  Tessellator(double limit_m, std::size_t max_points, ImportReport& report)
      : limit_m_(limit_m), max_points_(max_points), report_(report) {}

  /// The entity (not an INSERT) as world shapes, chords within `tolerance_m` of the arcs.
  /// @throw FloorPlanError(where) for absurd coordinates or when the drawing exceeds max_points.
  std::vector<WorldShape> shapes(const dxf::Entity& e, const Eigen::Affine3d& to_world, double tolerance_m,
                                 const std::string& where) {
    std::vector<WorldShape> out;
    const Eigen::Matrix3d ocs = ocs_to_wcs(e.extrusion);
    const Eigen::Affine3d ocs_to_world = to_world * Eigen::Affine3d(Eigen::Matrix3d(ocs));
    const double stretch = plane_stretch(ocs_to_world);
    const double tol = stretch > 0.0 ? tolerance_m / stretch : std::numeric_limits<double>::infinity();
    auto world = [&](const Eigen::Affine3d& m, double x, double y, double z) {
      const Eigen::Vector3d p = m * Eigen::Vector3d(x, y, z);
      return Eigen::Vector2d(p.x(), p.y());
    };
    if (const auto* line = std::get_if<dxf::Line>(&e.shape)) {
      WorldShape s;
      s.points = {world(to_world, line->start.x(), line->start.y(), line->start.z()),
                  world(to_world, line->end.x(), line->end.y(), line->end.z())};
      out.push_back(std::move(s));
    } else if (const auto* arc = std::get_if<dxf::Arc>(&e.shape)) {
      // Equal angles are a degenerate arc (as ezdxf reads them), different angles that agree modulo 360° a whole
      // circle.
      double span = std::fmod(arc->end_angle_deg - arc->start_angle_deg, 360.0);
      if (span <= 0.0) span += 360.0;
      if (arc->end_angle_deg == arc->start_angle_deg) span = 0.0;
      const double a0 = arc->start_angle_deg * kPi / 180.0;
      const double sweep = span * kPi / 180.0;
      const std::size_t n = span == 0.0 ? 0 : segments(arc->radius, sweep, tol);
      WorldShape s;
      for (std::size_t i = 0; i <= n; ++i) {
        const double a = i == n ? (arc->start_angle_deg + span) * kPi / 180.0
                                : a0 + sweep * static_cast<double>(i) / static_cast<double>(n);
        s.points.push_back(world(ocs_to_world, arc->center.x() + arc->radius * std::cos(a),
                                 arc->center.y() + arc->radius * std::sin(a), arc->center.z()));
      }
      out.push_back(std::move(s));
    } else if (const auto* circle = std::get_if<dxf::Circle>(&e.shape)) {
      const std::size_t n = segments(circle->radius, 2.0 * kPi, tol);
      WorldShape s;
      s.closed = true;
      for (std::size_t i = 0; i < n; ++i) {
        const double a = 2.0 * kPi * static_cast<double>(i) / static_cast<double>(n);
        s.points.push_back(world(ocs_to_world, circle->center.x() + circle->radius * std::cos(a),
                                 circle->center.y() + circle->radius * std::sin(a), circle->center.z()));
      }
      out.push_back(std::move(s));
    } else if (const auto* el = std::get_if<dxf::Ellipse>(&e.shape)) {
      // In WCS: no OCS, but the extrusion orients the minor axis (and so the direction of travel).
      const Eigen::Vector3d minor = el->ratio * e.extrusion.cross(el->major_axis);
      double span = std::fmod(el->end_param - el->start_param, 2.0 * kPi);
      if (span <= 1e-12) span += 2.0 * kPi;
      const bool whole = std::abs(span - 2.0 * kPi) <= 1e-12;
      const double major_stretch = plane_stretch(to_world);
      const double el_tol = major_stretch > 0.0 ? tolerance_m / major_stretch : std::numeric_limits<double>::infinity();
      const std::size_t n = segments(el->major_axis.norm(), span, el_tol);
      WorldShape s;
      s.closed = whole;
      for (std::size_t i = 0; i < (whole ? n : n + 1); ++i) {
        const double t =
            i == n ? el->start_param + span : el->start_param + span * static_cast<double>(i) / static_cast<double>(n);
        const Eigen::Vector3d p = el->center + std::cos(t) * el->major_axis + std::sin(t) * minor;
        s.points.push_back(world(to_world, p.x(), p.y(), p.z()));
      }
      out.push_back(std::move(s));
    } else if (const auto* poly = std::get_if<dxf::Polyline>(&e.shape)) {
      const auto& v = poly->vertices;
      std::vector<Eigen::Vector2d> pts;
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (i == 0) pts.push_back(v[0].point);
        if (i + 1 < v.size()) append_bulge(pts, v[i].point, v[i + 1].point, poly->is_3d ? 0.0 : v[i].bulge, tol);
      }
      if (poly->closed && v.size() > 1) {
        append_bulge(pts, v.back().point, v.front().point, poly->is_3d ? 0.0 : v.back().bulge, tol);
        pts.pop_back();  // the first point again
      }
      const Eigen::Affine3d& m = poly->is_3d ? to_world : ocs_to_world;
      const double z = poly->is_3d ? 0.0 : poly->elevation;
      WorldShape s;
      s.closed = poly->closed;
      for (const auto& p : pts) s.points.push_back(world(m, p.x(), p.y(), z));
      out.push_back(std::move(s));
    }
    for (const auto& s : out) {
      points_ += s.points.size();
      for (const auto& p : s.points) internal::check_world_point(p, limit_m_, where);
    }
    if (points_ > max_points_)
      throw FloorPlanError(where, "the drawing expands to more than " + std::to_string(max_points_) +
                                      " points (nested or repeated block references?)");
    return out;
  }

 private:
  /// Largest factor by which the map stretches lengths of the OCS plane, as seen in the world XY plane.
  static double plane_stretch(const Eigen::Affine3d& m) {
    const Eigen::Matrix2d a = m.linear().topLeftCorner<2, 2>();
    return Eigen::JacobiSVD<Eigen::Matrix2d>(a).singularValues()(0);
  }

  /// Chords for an arc of `radius` and |sweep| [rad] with sagitta ≤ tol (same units), at least one per 45°.
  std::size_t segments(double radius, double sweep, double tol) {
    double step = kPi / 4.0;
    if (tol < radius) step = std::min(step, 2.0 * std::acos(1.0 - tol / radius));
    const double n = std::ceil(std::abs(sweep) / step - 1e-9);
    if (n > static_cast<double>(kMaxArcSegments)) {
      if (!warned_)
        report_.warnings.push_back("some arcs are so large that " + std::to_string(kMaxArcSegments) +
                                   " chords do not meet the arc tolerance");
      warned_ = true;
      return kMaxArcSegments;
    }
    return std::max<std::size_t>(1, static_cast<std::size_t>(n));
  }

  /// Appends the points after p0 up to p1 of a straight (bulge 0) or arc segment, in OCS coordinates.
  void append_bulge(std::vector<Eigen::Vector2d>& out, const Eigen::Vector2d& p0, const Eigen::Vector2d& p1,
                    double bulge, double tol) {
    const Eigen::Vector2d d = p1 - p0;
    if (bulge == 0.0 || d.norm() == 0.0) {
      out.push_back(p1);
      return;
    }
    // Centre at distance (c/2)·cot(θ/2) = c·(1/b − b)/4 from the chord's middle, to its left for b > 0 (θ = 4·atan b).
    const Eigen::Vector2d left(-d.y(), d.x());
    const Eigen::Vector2d center = 0.5 * (p0 + p1) + left * ((1.0 / bulge - bulge) / 4.0);
    const double radius = (p0 - center).norm();
    const double a0 = std::atan2(p0.y() - center.y(), p0.x() - center.x());
    const double sweep = 4.0 * std::atan(bulge);
    const std::size_t n = segments(radius, sweep, tol);
    for (std::size_t i = 1; i < n; ++i) {
      const double a = a0 + sweep * static_cast<double>(i) / static_cast<double>(n);
      out.push_back(center + radius * Eigen::Vector2d(std::cos(a), std::sin(a)));
    }
    out.push_back(p1);
  }

  double limit_m_;
  std::size_t max_points_;
  ImportReport& report_;
  std::size_t points_ = 0;
  bool warned_ = false;
};

class DxfImporter {
 public:
  DxfImporter(const dxf::Document& doc, const LayerMapping& mapping, const DxfImportOptions& options, double units,
              ImportReport& report)
      : doc_(doc),
        mapping_(mapping),
        options_(options),
        report_(report),
        tessellator_(options.limits.max_abs_coordinate_m, options.max_total_points, report),
        builder_(options.name, options.limits),
        fine_tolerance_m_(std::min(options.arc_tolerance_m, mapping.cluster_tolerance_m / 4.0)) {
    model_.to_world = Eigen::Affine3d::Identity();
    model_.to_world.scale(units);
  }

  FloorPlan run() && {
    check_block_cycles();
    for (const auto& e : doc_.entities) entity(e, model_, true);
    finish_clusters();
    report_.objects = builder_.size();
    report_.extent = builder_.extent();
    for (const auto& [key, state] : layers_)
      if (state.report->status == "unknown" && mapping_.unknown_layers == UnknownLayerPolicy::kReport)
        report_.unknown_layers.push_back(state.name);
    std::sort(report_.unknown_layers.begin(), report_.unknown_layers.end());
    return std::move(builder_).finish();
  }

 private:
  struct LayerState {
    std::string name;
    const LayerRule* rule = nullptr;
    LayerReport* report = nullptr;
    std::size_t pool = 0;  // index into pools_ for cluster layers
  };
  struct ClusterItem {
    std::string key;    // handle chain of the entity
    std::string where;  // error path
    std::vector<WorldShape> shapes;
    std::vector<std::vector<Eigen::Vector2d>> fine;  // finer chords for the connectivity test
  };
  struct Pool {
    LayerState* layer = nullptr;
    std::vector<ClusterItem> items;
  };

  LayerState& layer(const std::string& name) {
    const auto key = dxf::to_upper_ascii(name);
    auto it = layers_.find(key);
    if (it != layers_.end()) return it->second;
    LayerState state;
    state.name = name;
    state.rule = mapping_.match_layer(name);
    state.report = &report_.layers[name];
    if (!state.rule) {
      state.report->status = "unknown";
      if (mapping_.unknown_layers == UnknownLayerPolicy::kError)
        throw FloorPlanError("layer " + name,
                             "no rule of the layer mapping matches this layer "
                             "(unknown_layers is \"error\")");
    } else {
      state.report->rule = state.rule->pattern;
      state.report->status = state.rule->ignore ? "ignored" : state.rule->cluster ? "clustered" : "mapped";
      if (state.rule->cluster && !state.rule->ignore) {
        state.pool = pools_.size();
        pools_.emplace_back();
      }
    }
    auto& stored = layers_.emplace(key, std::move(state)).first->second;
    if (stored.rule && stored.rule->cluster && !stored.rule->ignore) pools_[stored.pool].layer = &stored;
    return stored;
  }

  static std::string effective_layer(const dxf::Entity& e, const Frame& f) {
    return (e.layer == "0" && !f.layer.empty()) ? f.layer : e.layer;
  }

  void entity(const dxf::Entity& e, const Frame& f, bool top_level) {
    LayerState& ls = layer(effective_layer(e, f));
    if (top_level) ++ls.report->entities;
    if (std::holds_alternative<dxf::Insert>(e.shape)) {
      insert(e, f, ls);
      return;
    }
    if (!ls.rule) {
      ++report_.skipped["on unknown layers"];
      return;
    }
    if (ls.rule->ignore) {
      ++report_.skipped["on ignored layers"];
      return;
    }
    const std::string where = f.where + e.describe();
    auto shapes = tessellator_.shapes(e, f.to_world, options_.arc_tolerance_m, where);
    const std::string key = f.id + entity_key(e);
    if (ls.rule->cluster) {
      if (!has_edge(shapes)) {
        ++report_.skipped["degenerate " + e.type];
        return;
      }
      ClusterItem item{key, where, std::move(shapes), {}};
      const auto& fine_shapes = fine_tolerance_m_ < options_.arc_tolerance_m
                                    ? tessellator_.shapes(e, f.to_world, fine_tolerance_m_, where)
                                    : item.shapes;
      for (const auto& s : fine_shapes) {
        auto pts = s.points;
        if (s.closed && pts.size() > 2) pts.push_back(pts.front());
        item.fine.push_back(std::move(pts));
      }
      pools_[ls.pool].items.push_back(std::move(item));
      return;
    }
    if (builder_.add(ls.rule->kind + "-" + key, ls.rule->kind, ls.rule->attributes, shapes, std::nullopt, where)) {
      ++ls.report->objects;
    } else {
      ++report_.skipped["degenerate " + e.type];
    }
  }

  static bool has_edge(const std::vector<WorldShape>& shapes) {
    for (const auto& s : shapes)
      for (std::size_t i = 1; i < s.points.size(); ++i)
        if ((s.points[i] - s.points[i - 1]).norm() > 0.0) return true;
    return false;
  }

  /// The frames of an INSERT's block (one per MINSERT cell) and the id suffix of each cell.
  std::vector<std::pair<Frame, std::string>> insert_frames(const dxf::Entity& e, const Frame& parent,
                                                           const dxf::Block& block, const std::string& layer_name) {
    const auto& ins = std::get<dxf::Insert>(e.shape);
    if (parent.stack.size() >= kMaxNesting)
      throw FloorPlanError(parent.where + e.describe(), "blocks nested deeper than " + std::to_string(kMaxNesting));
    const Eigen::Affine3d before = parent.to_world * Eigen::Affine3d(Eigen::Matrix3d(ocs_to_wcs(e.extrusion))) *
                                   Eigen::Translation3d(ins.insert_point) *
                                   Eigen::AngleAxisd(ins.rotation_deg * kPi / 180.0, Eigen::Vector3d::UnitZ());
    Eigen::Affine3d after = Eigen::Affine3d::Identity();
    after.scale(ins.scale);
    after.translate(-block.base_point);
    std::vector<std::pair<Frame, std::string>> frames;
    for (int row = 0; row < ins.rows; ++row) {
      for (int col = 0; col < ins.columns; ++col) {
        if (++expansions_ > kMaxInsertExpansions)
          throw FloorPlanError(
              parent.where + e.describe(),
              "the drawing expands to more than " + std::to_string(kMaxInsertExpansions) + " block references");
        Frame f;
        const Eigen::Vector3d offset(col * ins.column_spacing, row * ins.row_spacing, 0.0);
        f.to_world = before * Eigen::Translation3d(offset) * after;
        const std::string cell =
            ins.rows * ins.columns > 1 ? "_r" + std::to_string(row + 1) + "c" + std::to_string(col + 1) : std::string();
        f.layer = layer_name;
        f.id = parent.id + entity_key(e) + cell + ".";
        f.where = parent.where + e.describe() + " > ";
        f.stack = parent.stack;
        f.stack.push_back(dxf::to_upper_ascii(block.name));
        frames.emplace_back(std::move(f), cell);
      }
    }
    return frames;
  }

  const dxf::Block* block_of(const dxf::Entity& e) {
    const auto& name = std::get<dxf::Insert>(e.shape).block;
    const auto* block = doc_.find_block(name);
    if (!block) {
      ++report_.skipped["INSERT of undefined block"];
      if (warned_blocks_.insert(dxf::to_upper_ascii(name)).second)
        report_.warnings.push_back("block '" + name + "' is referenced but not defined: its INSERTs are skipped");
    }
    return block;
  }

  void insert(const dxf::Entity& e, const Frame& f, LayerState& ls) {
    if (ls.rule && ls.rule->ignore) {
      ++report_.skipped["on ignored layers"];
      return;
    }
    const dxf::Block* block = block_of(e);
    if (!block) return;
    const LayerRule* rule = mapping_.match_block(block->name);
    if (rule && rule->ignore) {
      ++report_.skipped["INSERT of ignored block"];
      return;
    }
    for (auto& [frame, cell] : insert_frames(e, f, *block, ls.name)) {
      ++report_.block_inserts;
      if (!rule) {
        for (const auto& child : block->entities) entity(child, frame, false);
        continue;
      }
      std::vector<WorldShape> shapes;
      collect(*block, frame, shapes);
      const std::string where = f.where + e.describe();
      if (builder_.add(rule->kind + "-" + f.id + entity_key(e) + cell, rule->kind, rule->attributes, shapes,
                       pose_of(frame, *block), where)) {
        ++report_.block_objects;
        ++ls.report->objects;
      } else {
        ++report_.skipped["degenerate INSERT"];
      }
    }
  }

  /// The object frame of a block object: the world image of the base point, θ of the block's x axis.
  static fusion::Pose2D pose_of(const Frame& f, const dxf::Block& block) {
    const Eigen::Vector3d origin = f.to_world * block.base_point;
    const Eigen::Vector3d x_axis = f.to_world.linear() * Eigen::Vector3d::UnitX();
    const double theta = std::hypot(x_axis.x(), x_axis.y()) > 1e-12 ? std::atan2(x_axis.y(), x_axis.x()) : 0.0;
    return {origin.x(), origin.y(), theta};
  }

  /// Every shape of a mapped block, nested blocks included, except entities on ignored layers.
  void collect(const dxf::Block& block, const Frame& f, std::vector<WorldShape>& out) {
    for (const auto& child : block.entities) {
      const std::string layer_name = effective_layer(child, f);
      const LayerRule* rule = mapping_.match_layer(layer_name);
      if (rule && rule->ignore) continue;
      if (std::holds_alternative<dxf::Insert>(child.shape)) {
        const dxf::Block* nested = block_of(child);
        if (!nested) continue;
        const LayerRule* nested_rule = mapping_.match_block(nested->name);
        if (nested_rule && nested_rule->ignore) continue;
        for (auto& [frame, cell] : insert_frames(child, f, *nested, layer_name)) {
          ++report_.block_inserts;
          collect(*nested, frame, out);
        }
        continue;
      }
      auto shapes = tessellator_.shapes(child, f.to_world, options_.arc_tolerance_m, f.where + child.describe());
      for (auto& s : shapes) out.push_back(std::move(s));
    }
  }

  void finish_clusters() {
    internal::WorkBudget budget;
    for (auto& pool : pools_) {
      if (pool.items.empty()) continue;
      std::vector<std::vector<std::vector<Eigen::Vector2d>>> fine;
      fine.reserve(pool.items.size());
      for (const auto& item : pool.items) fine.push_back(item.fine);
      const auto cluster =
          internal::cluster_items(fine, mapping_.cluster_tolerance_m, mapping_.merge_enclosed_clusters, budget);
      const std::size_t count = cluster.empty() ? 0 : *std::max_element(cluster.begin(), cluster.end()) + 1;
      std::vector<std::vector<std::size_t>> members(count);
      for (std::size_t i = 0; i < cluster.size(); ++i) members[cluster[i]].push_back(i);
      const LayerRule& rule = *pool.layer->rule;
      for (const auto& m : members) {
        std::vector<WorldShape> shapes;
        for (std::size_t i : m)
          for (const auto& s : pool.items[i].shapes) shapes.push_back(s);
        const auto& first = pool.items[m.front()];
        if (builder_.add(rule.kind + "-" + first.key, rule.kind, rule.attributes, shapes, std::nullopt, first.where)) {
          ++report_.clustered_objects;
          ++pool.layer->report->objects;
        } else {
          ++report_.skipped["degenerate cluster"];
        }
      }
    }
  }

  void check_block_cycles() const {
    std::map<std::string, int> state;  // 1: being visited, 2: done
    std::vector<std::string> path;
    for (const auto& [key, block] : doc_.blocks) visit(key, block, state, path);
  }

  void visit(const std::string& key, const dxf::Block& block, std::map<std::string, int>& state,
             std::vector<std::string>& path) const {
    if (state[key] == 2) return;
    if (path.size() >= kMaxNesting)
      throw FloorPlanError("block " + block.name, "blocks nested deeper than " + std::to_string(kMaxNesting));
    state[key] = 1;
    path.push_back(block.name);
    for (const auto& child : block.entities) {
      const auto* ins = std::get_if<dxf::Insert>(&child.shape);
      if (!ins) continue;
      const auto* nested = doc_.find_block(ins->block);
      if (!nested) continue;
      const auto nested_key = dxf::to_upper_ascii(nested->name);
      if (state[nested_key] == 1) {
        std::string cycle;
        bool on = false;
        for (const auto& name : path) {
          on = on || dxf::to_upper_ascii(name) == nested_key;
          if (on) cycle += name + " → ";
        }
        throw FloorPlanError("block " + block.name + " > " + child.describe(),
                             "block '" + nested->name + "' inserts itself (" + cycle + nested->name + ")");
      }
      visit(nested_key, *nested, state, path);
    }
    path.pop_back();
    state[key] = 2;
  }

  const dxf::Document& doc_;
  const LayerMapping& mapping_;
  const DxfImportOptions& options_;
  ImportReport& report_;
  Tessellator tessellator_;
  internal::PlanBuilder builder_;
  double fine_tolerance_m_;
  Frame model_;
  std::map<std::string, LayerState> layers_;  // key: upper-case layer name
  std::vector<Pool> pools_;
  std::set<std::string> warned_blocks_;
  std::size_t expansions_ = 0;
};

}  // namespace

ImportResult import_dxf(std::string_view text, const LayerMapping& mapping, const DxfImportOptions& options) {
  if (options.units_to_m && !(std::isfinite(*options.units_to_m) && *options.units_to_m > 0.0))
    throw std::invalid_argument("import_dxf: units_to_m must be finite and > 0");
  if (!(std::isfinite(options.unitless_to_m) && options.unitless_to_m > 0.0))
    throw std::invalid_argument("import_dxf: unitless_to_m must be finite and > 0");
  if (!(std::isfinite(options.arc_tolerance_m) && options.arc_tolerance_m >= 1e-6))
    throw std::invalid_argument("import_dxf: arc_tolerance_m must be finite and >= 1e-6");
  if (!(std::isfinite(mapping.cluster_tolerance_m) && mapping.cluster_tolerance_m > 0.0))
    throw std::invalid_argument("import_dxf: mapping.cluster_tolerance_m must be finite and > 0");

  const dxf::Document doc = dxf::read_dxf(text);
  ImportResult result;
  ImportReport& report = result.report;
  report.format = "dxf";
  report.version = doc.version;
  double units = options.unitless_to_m;
  if (options.units_to_m) {
    units = *options.units_to_m;
    report.units_source = "override";
  } else if (doc.insunits && dxf::insunits_to_metres(*doc.insunits)) {
    units = *dxf::insunits_to_metres(*doc.insunits);
    report.units_source = "$INSUNITS " + std::to_string(*doc.insunits) + " (" + dxf::insunits_name(*doc.insunits) + ")";
  } else {
    report.units_source = doc.insunits ? "$INSUNITS " + std::to_string(*doc.insunits) + " (" +
                                             dxf::insunits_name(*doc.insunits) + "): default"
                                       : std::string("no $INSUNITS: default");
    report.warnings.push_back("the drawing does not say its units: assumed " + std::to_string(units) +
                              " m per unit (set the unit override if that is wrong)");
  }
  report.units_to_m = units;
  report.entity_counts = doc.entity_counts;
  for (const auto& [type, count] : doc.skipped_entities) report.skipped[type] += count;
  for (const auto& [key, block] : doc.blocks) {
    // The layout blocks hold paper-space content (viewports...), not parts of the plan.
    if (key.rfind("*MODEL_SPACE", 0) == 0 || key.rfind("*PAPER_SPACE", 0) == 0) continue;
    for (const auto& [type, count] : block.skipped_entities) report.skipped[type + " (in block definitions)"] += count;
  }
  if (doc.paper_space_entities > 0) report.skipped["paper space"] = doc.paper_space_entities;

  result.plan = DxfImporter(doc, mapping, options, units, report).run();
  if (result.plan.objects.empty())
    report.warnings.push_back("no object was imported: check the layer mapping against the report's layers");
  return result;
}

}  // namespace wm::apriori
