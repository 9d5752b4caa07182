#pragma once

// The small floor plan the world and handler tests share: a solid wall along y = 10 from x = 0 to 20, and a
// 1.2 m × 0.8 m not-deformable table at (5, 5) turned by 0.3 rad.
#include "apriori/floor_plan.h"

namespace wm::testing {

inline apriori::FloorPlan lab_plan() {
  apriori::PlanObject wall;
  wall.id = "wall-n";
  wall.kind = "wall";
  wall.attributes = {"solid"};
  wall.polylines = {{{0, 10}, {20, 10}}};
  apriori::PlanObject table;
  table.id = "table-1";
  table.kind = "table";
  table.attributes = {"not_deformable"};
  table.pose = {5, 5, 0.3};
  table.polygon = {{-0.6, -0.4}, {0.6, -0.4}, {0.6, 0.4}, {-0.6, 0.4}};
  return {"lab", {wall, table}};
}

}  // namespace wm::testing
