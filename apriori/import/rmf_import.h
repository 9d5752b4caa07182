#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "apriori/floor_plan.h"
#include "apriori/import/import_report.h"
#include "apriori/import/layer_mapping.h"

namespace wm::apriori {

/// Options of import_rmf_building.
struct RmfImportOptions {
  /// The level to import; empty: the only level, or the lowest (by elevation, then file order) with a warning.
  std::string level;
  /// Metres per pixel, overriding the level's measurements (reference_image maps only).
  std::optional<double> metres_per_pixel;
  std::vector<std::string> wall_attributes{"solid"};
  /// Doors are imported closed (a segment between their two vertices); `movable` is what the example rule
  /// rules/examples/movable.pl knows.
  std::vector<std::string> door_attributes{"movable"};
  /// Kinds and attributes of `models` (furniture), matched against the model_name ("OpenRobotics/OfficeChairBlack");
  /// first match wins. A model no rule matches becomes {"furniture", {"not_deformable"}}; an `ignore` rule skips it.
  std::vector<LayerRule> model_rules;
  /// A building.yaml holds no model footprints (they are Gazebo meshes), so each model becomes a rectangle of this
  /// size [m] (length along the model's x axis, width), centred on the model and turned by its yaw; `model_sizes`
  /// overrides it per model_name glob (first match wins).
  Eigen::Vector2d default_model_size_m{0.5, 0.5};
  std::vector<std::pair<std::string, Eigen::Vector2d>> model_sizes;
  std::string name = "rmf import";
  FloorPlanLimits limits;
};

/// Converts an Open-RMF traffic-editor `*.building.yaml` level into a floor plan: every wall (pair of vertices)
/// becomes a `wall` object, every door a `door` object (closed), every static model a rectangle posed at the model
/// with its yaw (non-static models, i.e. robots, are skipped). Floors, lanes and image layers are not obstacles
/// and are only counted.
/// Coordinates: for `coordinate_system: reference_image` (the default) vertices are pixels of the level's drawing
/// with y down; as the RMF building_map tools do, y is negated and everything is scaled by the mean of
/// distance / pixel length over the level's `measurements`. `cartesian_meters` maps are used as they are.
/// Object ids: "wall-<i>" and "door-<name or i>" in file order, models by their `name` (made unique).
/// @throw FloorPlanError with the YAML path ("levels.L1.walls[3]") or "line N" for malformed YAML; a level without
///        measurements (and no override), an unknown coordinate system, a vertex index out of range and absurd
///        coordinates are errors.
/// @throw std::invalid_argument for a non-positive or non-finite metres_per_pixel or model size.
ImportResult import_rmf_building(std::string_view yaml_text, const RmfImportOptions& options = {});

/// The levels of a building.yaml by elevation (then file order), lowest first: each imports as its own floor plan
/// (RmfImportOptions::level). @throw FloorPlanError for text that is not UTF-8, malformed YAML or no levels.
std::vector<std::string> rmf_level_names(std::string_view yaml_text);

}  // namespace wm::apriori
