#include <algorithm>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>

#include "apriori/import/amrl_import.h"
#include "apriori/import/dxf_import.h"
#include "apriori/import/rmf_import.h"
#include "tools/raycast/raycast.h"
#include "tools/truth/world.h"
#include "tools/truth/world_internal.h"

// The buildings' plans loaded from the shared data, with their routes and the table placed beside them.
namespace wm::truth {
using namespace internal;

namespace {

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<Polyline> truncate_route(const std::vector<Polyline>& route, double max_m) {
  if (max_m <= 0) return route;
  std::vector<Polyline> kept;
  double left = max_m;
  for (const auto& line : route) {
    if (left <= 0) break;
    Polyline part{line.front()};
    for (std::size_t k = 0; k + 1 < line.size() && left > 0; ++k) {
      const double length = (line[k + 1] - line[k]).norm();
      if (length <= left) {
        part.push_back(line[k + 1]);
        left -= length;
      } else {
        part.push_back(line[k] + (line[k + 1] - line[k]) * (left / length));
        left = 0;
      }
    }
    if (part.size() >= 2) kept.push_back(std::move(part));
  }
  return kept;
}

apriori::ImportResult import_building(const std::string& name, const std::filesystem::path& data_dir) {
  if (name == "gdc1" || name == "ahg2") {
    const auto file = data_dir / "amrl-vectormaps" / (name == "gdc1" ? "GDC1.vectormap.json" : "AHG2.vectormap.json");
    return apriori::import_amrl_vectormap(read_text(file));
  }
  if (name == "rmf-office")
    return apriori::import_rmf_building(read_text(data_dir / "rmf-office" / "office.building.yaml"));
  if (name == "barcelona")
    return apriori::import_dxf(read_text(data_dir / "barcelona-pavilion" / "plan.dxf"),
                               apriori::default_layer_mapping());
  throw std::runtime_error("unknown building " + name + " (gdc1, ahg2, rmf-office, barcelona)");
}

/// The table beside the route: 1–2.1 m to its side, along it, clear of walls and route by 0.7 m, so that a shift of
/// up to 0.5 m leaves it clear of both.
fusion::Pose2D place_table(const std::vector<PlanWall>& walls, const std::vector<Polyline>& route, std::mt19937& rng) {
  auto poses = route_poses(route, 0.5);
  std::shuffle(poses.begin(), poses.end(), rng);
  for (const auto& pose : poses)
    for (const double offset : {1.0, 1.3, 1.7, 2.1})
      for (const double side : {1.0, -1.0}) {
        const Vec normal(-std::sin(pose.theta_rad), std::cos(pose.theta_rad));
        const Vec centre = Vec(pose.x_m, pose.y_m) + side * offset * normal;
        const fusion::Pose2D table{centre.x(), centre.y(), pose.theta_rad};
        bool clear = inside(walls, centre);
        for (const auto& [a, b] : table_sides(table)) {
          if (!clear) break;
          for (const auto& w : walls) clear = clear && segment_distance(a, b, w.p0, w.p1) >= 0.7;
          clear = clear && route_distance(route, a, b) >= 0.7;
        }
        if (clear) return table;
      }
  throw std::runtime_error("no place for the table beside the route");
}

}  // namespace

std::vector<std::string> building_names() { return {"gdc1", "ahg2", "rmf-office", "barcelona"}; }

Building load_building(const std::string& name, const std::filesystem::path& data_dir, unsigned seed,
                       double max_route_m) {
  auto imported = import_building(name, data_dir);
  Building building;
  building.name = name;
  building.plan.name = "truth " + name;
  for (auto& object : imported.plan.objects) {
    if (!object.has_attribute("solid") || object.kind == "door") continue;
    const bool glass = object.has_attribute("glass");
    const auto edges = object.edges();
    for (std::size_t k = 0; k < edges.size(); ++k) {
      const Vec p0 = object.pose.transform_point(edges[k].p0), p1 = object.pose.transform_point(edges[k].p1);
      if ((p1 - p0).norm() < 0.01) continue;
      if (!glass) building.walls.push_back({object.id, k, p0, p1});
      building.enclosure.push_back({object.id, k, p0, p1});
    }
    if (!glass) building.plan.objects.push_back(std::move(object));
  }
  if (building.walls.empty()) throw std::runtime_error(name + ": no wall in the plan");
  if (name == "gdc1") {
    for (const auto& line : raycast::gdc1_route()) building.route.push_back(line);
  } else {
    building.route = {auto_route(building.enclosure, seed)};
  }
  building.route = truncate_route(building.route, max_route_m);
  std::mt19937 rng(seed * 7919u + 1);
  building.table = place_table(building.enclosure, building.route, rng);
  apriori::PlanObject table;
  table.id = kTableId;
  table.kind = "table";
  table.attributes = {"not_deformable"};
  table.pose = building.table;
  const double hx = kTableLengthM / 2, hy = kTableWidthM / 2;
  table.polygon = {{-hx, -hy}, {hx, -hy}, {hx, hy}, {-hx, hy}};
  building.plan.objects.push_back(std::move(table));
  return building;
}

}  // namespace wm::truth
