#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <string>

#include "apriori/import/dxf_import.h"
#include "tests/apriori/plan_test_support.h"

// Round trip against an independent DXF implementation: tools/make_ezdxf_plans.py writes drawings with ezdxf and,
// for each, the geometry ezdxf reads back (world frame, metres). Every imported object must trace exactly that
// geometry: endpoints and arc centres to 1e-9 relative, chord vertices on the arcs, and the same signed sweep.

namespace wm::apriori {
namespace {

using nlohmann::json;
using test::ezdxf_plans_dir;
using test::read_file;

constexpr double kPi = 3.14159265358979323846;
constexpr double kRel = 1e-9;

double tol(const Eigen::Vector2d& p) { return kRel * (1.0 + p.norm()); }
Eigen::Vector2d vec(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>()}; }
bool same(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return (a - b).norm() <= tol(a) + tol(b); }

double wrap(double a) {
  while (a > kPi) a -= 2 * kPi;
  while (a <= -kPi) a += 2 * kPi;
  return a;
}

/// The parameter angle of p on a primitive's circle or ellipse.
double angle_on(const json& prim, const Eigen::Vector2d& p) {
  const Eigen::Vector2d d = p - vec(prim["center"]);
  if (prim["type"] == "ellipse") {
    const Eigen::Vector2d major = vec(prim["major"]), minor = vec(prim["minor"]);
    return std::atan2(d.dot(minor) / minor.squaredNorm(), d.dot(major) / major.squaredNorm());
  }
  return std::atan2(d.y(), d.x());
}

/// Empty when p lies on the primitive's curve, else why not.
std::string off_curve(const json& prim, const Eigen::Vector2d& p) {
  const std::string type = prim["type"];
  if (type == "line") {
    const Eigen::Vector2d a = vec(prim["start"]), b = vec(prim["end"]);
    const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    if ((a + t * (b - a) - p).norm() <= tol(p)) return {};
    return "point off the line";
  }
  const Eigen::Vector2d c = vec(prim["center"]);
  if (type == "ellipse") {
    const Eigen::Vector2d d = p - c, major = vec(prim["major"]), minor = vec(prim["minor"]);
    const double u = d.dot(major) / major.squaredNorm(), v = d.dot(minor) / minor.squaredNorm();
    if (std::abs(u * u + v * v - 1.0) <= 10 * kRel * (1.0 + c.norm() / minor.norm())) return {};
    return "point off the ellipse";
  }
  const double r = prim["radius"];
  if (std::abs((p - c).norm() - r) <= tol(p) + tol(c)) return {};
  return "point off the circle (distance " + std::to_string((p - c).norm()) + ", radius " + std::to_string(r) + ")";
}

/// Empty when the polyline traces the path of primitives from its first to its last point, else why not.
std::string traces(const std::vector<Eigen::Vector2d>& pts, const json& path) {
  if (pts.size() < 2) return "fewer than 2 points";
  if (path.size() == 1 && path[0]["type"] == "circle") {
    const auto& prim = path[0];
    if (!same(pts.front(), pts.back())) return "circle not closed";
    double sweep = 0.0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (auto why = off_curve(prim, pts[i]); !why.empty()) return why;
      if (i > 0) sweep += wrap(angle_on(prim, pts[i]) - angle_on(prim, pts[i - 1]));
    }
    if (pts.size() < 9) return "a circle needs at least 8 chords";
    if (std::abs(sweep - prim["sweep"].get<double>()) > 1e-9) return "circle sweep " + std::to_string(sweep);
    return {};
  }
  std::size_t at = 0;
  if (!same(pts[0], vec(path[0]["start"]))) return "does not start at the path's start";
  for (const auto& prim : path) {
    const Eigen::Vector2d end = vec(prim["end"]);
    double sweep = 0.0;
    std::size_t j = at + 1;
    for (; j < pts.size(); ++j) {
      if (auto why = off_curve(prim, pts[j]); !why.empty()) return why + " at point " + std::to_string(j);
      if (prim["type"] != "line") sweep += wrap(angle_on(prim, pts[j]) - angle_on(prim, pts[j - 1]));
      if (same(pts[j], end)) break;
    }
    if (j == pts.size()) return "never reaches the end of a " + prim["type"].get<std::string>();
    if (prim["type"] != "line" && std::abs(sweep - prim["sweep"].get<double>()) > 1e-9)
      return prim["type"].get<std::string>() + " sweep " + std::to_string(sweep) + " instead of " +
             std::to_string(prim["sweep"].get<double>());
    at = j;
  }
  if (at != pts.size() - 1) return "points beyond the end of the path";
  return {};
}

struct Case {
  json expected;
  ImportResult result;
};

Case import_case(const std::string& name, LayerMapping* mapping_out = nullptr) {
  const auto dir = ezdxf_plans_dir() + "/";
  Case c;
  c.expected = json::parse(read_file(dir + name + ".expected.json"));
  auto mapping = parse_layer_mapping_json(read_file(dir + c.expected["mapping"].get<std::string>()));
  if (mapping_out) *mapping_out = mapping;
  DxfImportOptions options;
  if (!c.expected["units_to_m"].is_null()) options.units_to_m = c.expected["units_to_m"].get<double>();
  c.result = import_dxf(read_file(dir + c.expected["dxf"].get<std::string>()), mapping, options);
  return c;
}

class EzdxfPlanTest : public ::testing::TestWithParam<const char*> {};

TEST_P(EzdxfPlanTest, ImportsTheGeometryEzdxfReadsBack) {
  const auto c = import_case(GetParam());
  const auto& ex = c.expected;
  const auto& plan = c.result.plan;
  const auto& report = c.result.report;

  EXPECT_EQ(report.version, ex["version"].get<std::string>());
  EXPECT_NEAR(report.units_to_m, ex["metres_per_unit"].get<double>(), kRel * ex["metres_per_unit"].get<double>());
  for (const auto& [type, n] : ex["entity_counts"].items()) {
    ASSERT_TRUE(report.entity_counts.count(type)) << type;
    EXPECT_EQ(report.entity_counts.at(type), n.get<std::size_t>()) << type;
  }
  EXPECT_EQ(report.entity_counts.size(), ex["entity_counts"].size());
  for (const auto& [type, n] : ex["skipped"].items()) {
    ASSERT_TRUE(report.skipped.count(type)) << type;
    EXPECT_EQ(report.skipped.at(type), n.get<std::size_t>()) << type;
  }
  EXPECT_EQ(report.unknown_layers, ex["unknown_layers"].get<std::vector<std::string>>());
  EXPECT_EQ(report.block_objects, ex["block_objects"].get<std::size_t>());
  EXPECT_EQ(report.clustered_objects, ex["clustered_objects"].get<std::size_t>());

  std::set<std::string> expected_ids, actual_ids;
  for (const auto& [id, o] : ex["objects"].items()) expected_ids.insert(id);
  for (const auto& o : plan.objects) actual_ids.insert(o.id);
  EXPECT_EQ(actual_ids, expected_ids);
  EXPECT_EQ(report.objects, plan.objects.size());

  for (const auto& [id, eo] : ex["objects"].items()) {
    const PlanObject* o = test::find_object(plan, id);
    if (!o) continue;  // reported by the id comparison above
    SCOPED_TRACE("object " + id);
    EXPECT_EQ(o->kind, eo["kind"].get<std::string>());
    EXPECT_EQ(o->attributes, eo["attributes"].get<std::vector<std::string>>());
    if (!eo["pose"].is_null()) {
      const Eigen::Vector2d p(eo["pose"]["x"].get<double>(), eo["pose"]["y"].get<double>());
      EXPECT_TRUE(same(Eigen::Vector2d(o->pose.x_m, o->pose.y_m), p))
          << o->pose.x_m << " " << o->pose.y_m << " vs " << p.transpose();
      EXPECT_NEAR(wrap(o->pose.theta_rad - eo["pose"]["theta"].get<double>()), 0.0, 1e-12);
    } else {
      EXPECT_EQ(o->pose.theta_rad, 0.0);  // loose entities and clusters: centroid frame, θ = 0
    }
    auto polylines = test::world_polylines(*o);
    ASSERT_EQ(polylines.size(), eo["paths"].size());
    std::vector<bool> used(polylines.size(), false);
    for (const auto& path : eo["paths"]) {
      std::string why;
      bool found = false;
      for (std::size_t k = 0; k < polylines.size() && !found; ++k) {
        if (used[k]) continue;
        const auto reason = traces(polylines[k], path);
        if (reason.empty()) {
          used[k] = found = true;
        } else {
          why += "\n  polyline " + std::to_string(k) + ": " + reason;
        }
      }
      EXPECT_TRUE(found) << "no polyline traces " << path.dump() << why;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Ezdxf, EzdxfPlanTest,
                         ::testing::Values("geometry_r12", "geometry_r2000", "geometry_r2010", "geometry_r2018",
                                           "units_in", "units_ft", "units_mm", "units_cm", "units_dm", "units_override",
                                           "clusters", "unknown_entities"));

TEST(EzdxfPlanTest, DegenerateAndIgnoredEntitiesAreCounted) {
  const auto c = import_case("geometry_r2010");
  const auto& r = c.result.report;
  EXPECT_EQ(r.skipped.at("degenerate LINE"), 1u);
  EXPECT_EQ(r.skipped.at("on unknown layers"), 1u);        // the MYSTERY line
  EXPECT_EQ(r.skipped.at("on ignored layers"), 1u);        // the TABLE_A insert on IGNORED
  EXPECT_EQ(r.skipped.at("INSERT of ignored block"), 1u);  // SKIP_ME
  EXPECT_EQ(r.layers.at("MYSTERY").status, "unknown");
  EXPECT_EQ(r.layers.at("LINES").rule, "LINES");
  EXPECT_EQ(r.layers.at("LINES").entities, 3u);
  EXPECT_EQ(r.layers.at("BLOCKS").entities, 8u);
  EXPECT_EQ(r.units_source, "$INSUNITS 6 (metres)");
  // 4 single TABLE_A inserts, 6 MINSERT cells, 2 ASSEMBLY inserts each with a nested SUB and TABLE_A.
  EXPECT_EQ(r.block_inserts, 4u + 6u + 2u * 3u);
}

TEST(EzdxfPlanTest, R12WithoutUnitsWarnsAndAssumesMetres) {
  const auto c = import_case("geometry_r12");
  EXPECT_EQ(c.result.report.units_to_m, 1.0);
  ASSERT_FALSE(c.result.report.warnings.empty());
  EXPECT_NE(c.result.report.warnings[0].find("does not say its units"), std::string::npos);
}

TEST(EzdxfPlanTest, WithoutEnclosureMergingButtonsStayObjectsOfTheirOwn) {
  LayerMapping mapping;
  import_case("clusters", &mapping);
  mapping.merge_enclosed_clusters = false;
  const auto text = read_file(ezdxf_plans_dir() + "/clusters.dxf");
  const auto result = import_dxf(text, mapping);
  EXPECT_EQ(result.report.clustered_objects, 3u + 6u + 2u);  // chairs, their buttons, table, lone line
  mapping.merge_enclosed_clusters = true;
  mapping.cluster_tolerance_m = 0.005;  // the 10 mm gap to the table no longer joins
  EXPECT_EQ(import_dxf(text, mapping).report.clustered_objects, 6u);
}

TEST(EzdxfPlanTest, BinaryDxfIsRefused) {
  const auto text = read_file(ezdxf_plans_dir() + "/binary.dxf");
  try {
    import_dxf(text, default_layer_mapping());
    FAIL() << "binary DXF accepted";
  } catch (const FloorPlanError& e) {
    EXPECT_NE(std::string(e.what()).find("binary DXF"), std::string::npos) << e.what();
  }
}

TEST(EzdxfPlanTest, TruncatedFilesAreRefusedWithTheLine) {
  const auto text = read_file(ezdxf_plans_dir() + "/geometry_r2010.dxf");
  const auto mapping = parse_layer_mapping_json(read_file(ezdxf_plans_dir() + "/mapping.json"));
  for (double fraction : {0.1, 0.5, 0.9, 0.999}) {
    SCOPED_TRACE(fraction);
    const auto cut = text.substr(0, static_cast<std::size_t>(fraction * static_cast<double>(text.size())));
    try {
      import_dxf(cut, mapping);
      FAIL() << "truncated file accepted";
    } catch (const FloorPlanError& e) {
      EXPECT_EQ(e.path().rfind("line ", 0), 0u) << e.what();
    }
  }
  const auto without_eof = text.substr(0, text.rfind("EOF"));
  EXPECT_THROW(import_dxf(without_eof, mapping), FloorPlanError);
}

TEST(EzdxfPlanTest, CorruptedFilesFailCleanly) {
  // Random damage (fixed seed) to a real drawing: every outcome is a plan or a FloorPlanError, nothing else.
  const auto text = read_file(ezdxf_plans_dir() + "/geometry_r2010.dxf");
  const auto mapping = parse_layer_mapping_json(read_file(ezdxf_plans_dir() + "/mapping.json"));
  std::mt19937 rng(20240601);
  const std::string alphabet = "0123456789-.eE \nAZ\r";
  std::size_t refused = 0;
  for (int round = 0; round < 300; ++round) {
    std::string damaged = text;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < edits; ++k) {
      const std::size_t at = rng() % damaged.size();
      switch (rng() % 3) {
        case 0:
          damaged[at] = alphabet[rng() % alphabet.size()];
          break;
        case 1:
          damaged.erase(at, 1 + rng() % 40);
          break;
        default:
          damaged.insert(at, damaged.substr(rng() % damaged.size(), 1 + rng() % 40));
          break;
      }
      if (damaged.empty()) damaged = "0";
    }
    try {
      import_dxf(damaged, mapping);
    } catch (const FloorPlanError&) {
      ++refused;
    }
  }
  EXPECT_GT(refused, 0u);
}

}  // namespace
}  // namespace wm::apriori
