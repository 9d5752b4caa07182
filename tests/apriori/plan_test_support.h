#pragma once

// Helpers for the apriori import tests: files, and world-frame views of imported objects.

#include <Eigen/Core>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "apriori/floor_plan.h"

namespace wm::apriori::test {

/// Files written at test time by tools/make_ezdxf_plans.py (ctest fixture apriori_ezdxf_plans).
inline std::string ezdxf_plans_dir() { return WM_EZDXF_PLANS_DIR; }
/// The shipped real plans (tests/data/plans).
inline std::string plans_data_dir() { return WM_PLANS_DATA_DIR; }

/// The whole file, bytes as they are. @throw std::runtime_error when it cannot be read.
inline std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw std::runtime_error("cannot read " + path +
                             " (files of ezdxf_plans are made by the ctest fixture apriori_ezdxf_plans: run ctest, "
                             "or tools/make_ezdxf_plans.py " WM_EZDXF_PLANS_DIR ")");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The object's outlines in the world frame: polylines, then the polygon closed by repeating its first point.
inline std::vector<std::vector<Eigen::Vector2d>> world_polylines(const PlanObject& o) {
  std::vector<std::vector<Eigen::Vector2d>> out;
  for (const auto& line : o.polylines) {
    out.emplace_back();
    for (const auto& p : line) out.back().push_back(o.pose.transform_point(p));
  }
  if (!o.polygon.empty()) {
    out.emplace_back();
    for (const auto& p : o.polygon) out.back().push_back(o.pose.transform_point(p));
    out.back().push_back(o.pose.transform_point(o.polygon.front()));
  }
  return out;
}

inline const PlanObject* find_object(const FloorPlan& plan, const std::string& id) {
  for (const auto& o : plan.objects)
    if (o.id == id) return &o;
  return nullptr;
}

}  // namespace wm::apriori::test
