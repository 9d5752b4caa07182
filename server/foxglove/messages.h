#pragma once

// The world model as Foxglove messages (JSON encoding, https://github.com/foxglove/schemas): the occupancy grid as
// foxglove.Grid, the observed elements and the floor plan as foxglove.SceneUpdate of line primitives, robot poses as
// foxglove.PoseInFrame and foxglove.FrameTransforms, decisions as foxglove.Log. Pure functions of values; every
// position is in the world frame [m], every angle [rad], every time [ns since the Unix epoch].
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "fusion/grid/grid_geometry.h"
#include "server/world/update.h"
#include "server/world/world_state.h"

namespace wm::foxglove {

/// The frame everything is drawn in: the world frame of the map and the grid.
inline constexpr std::string_view kMapFrame = "map";

/// Standard base64 (RFC 4648, with padding), what the JSON encoding of a Foxglove bytes field is.
std::string base64(std::string_view bytes);

/// One layer of a grid: width × height values, row-major from the lower-left cell, NaN = unknown.
struct GridField {
  std::string name;
  std::vector<float> values;
};

/// foxglove.Grid of `region`: `pose` is the lower-left corner of cell (0, 0) with no rotation, so row r (from the
/// bottom) and column c lie at origin + (c, r) · resolution, as in GET /api/v1/grid. Each cell packs one
/// little-endian FLOAT32 per field, in the order given (cell_stride = 4 · fields, row_stride = width · cell_stride).
/// @throw std::invalid_argument without fields, or when a field does not hold width × height values.
std::string grid_message(const fusion::GridGeometry& region, const std::vector<GridField>& fields,
                         std::uint64_t stamp_ns);

/// The smallest k >= 1 for which a width × height grid in k × k blocks has at most `max_cells` cells
/// (⌈w/k⌉·⌈h/k⌉ <= max_cells). @throw std::invalid_argument for max_cells = 0 or a size < 1.
std::int64_t coarsening_factor(std::int64_t width, std::int64_t height, std::size_t max_cells);

/// The grid in k × k blocks: each cell the largest known value of its block (NaN when none is known), so an
/// occupied cell stays visible; the region keeps its origin, its cells k times larger, ⌈w/k⌉ × ⌈h/k⌉ of them.
/// k = 1 returns it unchanged. @throw std::invalid_argument for k < 1 or a field of the wrong size.
std::pair<fusion::GridGeometry, std::vector<GridField>> coarsened(const fusion::GridGeometry& region,
                                                                  std::vector<GridField> fields, std::int64_t k);

/// Colour with components in [0, 1].
struct Rgba {
  double r = 0, g = 0, b = 0, a = 1;
};

/// One scene entity drawn as one LINE_LIST primitive (two points per segment, z = 0).
struct LineEntity {
  std::string id;
  std::vector<std::array<Eigen::Vector2d, 2>> segments;
  Rgba color;
  std::vector<std::pair<std::string, std::string>> metadata;  // shown by Foxglove when the entity is picked
};

/// The entity of an observed element: id = the element's id ("e12"), its segment, coloured by origin as the web
/// viewer draws it (scan, grid, client, other).
LineEntity element_entity(const world::Element& element);
/// The entity of a CAD object: id = the object's id, its edges in the world frame as placed (the same points as the
/// edges of GET /api/v1/map), coloured by attribute as the web viewer draws it (solid, not_deformable, other).
LineEntity object_entity(const world::ObjectState& object, const world::WorldOptions& options);

/// foxglove.SceneUpdate: `replace_all` starts it with a deletion of every entity of the topic (a whole state, not a
/// change), then one deletion per id of `deleted` (MATCHING_ID), then the entities, each replacing the one of its id.
std::string scene_update_message(const std::vector<LineEntity>& entities, const std::vector<std::string>& deleted,
                                 bool replace_all, std::uint64_t stamp_ns);

/// foxglove.PoseInFrame in the map frame: (x, y, 0) and the rotation θ about z.
std::string pose_in_frame_message(double x_m, double y_m, double theta_rad, std::uint64_t stamp_ns);

/// One planar transform: the child frame's origin and heading in the parent frame.
struct PlanarTransform {
  std::string parent_frame;
  std::string child_frame;
  double x_m = 0, y_m = 0, theta_rad = 0;
  std::uint64_t stamp_ns = 0;
};
/// foxglove.FrameTransforms.
std::string frame_transforms_message(const std::vector<PlanarTransform>& transforms);

/// foxglove.Log of one decision: level INFO (WARNING for a rule fallback), name = the rule, message "decision SEQ:
/// ACTION [element] [object] by OBSERVER (ORIGIN/SENSOR): EXPLANATION" with the action's wire name ("delete",
/// "merge"...).
std::string log_message(const world::DecisionRecord& decision, std::uint64_t stamp_ns);

}  // namespace wm::foxglove
