#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "apriori/floor_plan.h"

namespace wm::apriori {

/// How one source layer (DXF layer; "walls"/"doors"/"models" for Open-RMF; "segments" for AMRL) was imported.
struct LayerReport {
  std::size_t entities = 0;  // top-level entities read on this layer (model space; block contents not counted)
  std::size_t objects = 0;   // plan objects made from this layer's entities (block objects count on the INSERT's layer)
  std::string rule;          // pattern of the mapping rule that matched; empty when none did
  std::string status;        // "mapped", "clustered", "ignored" or "unknown"
};

/// World-frame bounding box of the imported objects [m].
struct Extent {
  Eigen::Vector2d min_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d max_m = Eigen::Vector2d::Zero();
};

/// What an import read, made and left out: shown to the user who loads a plan, so that a wrong mapping or unit
/// is visible at once.
struct ImportReport {
  std::string format;        // "dxf", "rmf-building", "amrl-vectormap"
  std::string version;       // DXF $ACADVER ("AC1027"); RMF level name; empty otherwise
  double units_to_m = 1.0;   // metres per source unit that was applied
  std::string units_source;  // how it was chosen, e.g. "$INSUNITS 6 (metres)", "override", "measurements"
  std::map<std::string, std::size_t> entity_counts;  // source entities by type (DXF: model space, every type)
  std::map<std::string, LayerReport> layers;         // by layer name as first seen
  std::vector<std::string> unknown_layers;           // layers no rule matched (policy "report"), sorted
  std::map<std::string, std::size_t> skipped;        // entities not imported, by reason ("TEXT", "degenerate LINE")
  std::size_t block_inserts = 0;      // INSERT references expanded (nested ones included, MINSERT cells each)
  std::size_t block_objects = 0;      // objects made from mapped blocks (one per INSERT / MINSERT cell)
  std::size_t clustered_objects = 0;  // objects made by clustering loose entities
  std::size_t objects = 0;            // objects in the plan
  std::optional<Extent> extent;       // nullopt when the plan is empty
  std::vector<std::string> warnings;  // e.g. "no $INSUNITS: assumed metres"
};

/// A converted plan and its report.
struct ImportResult {
  FloorPlan plan;
  ImportReport report;
};

/// The report as a JSON object (for the HTTP answer and `wmctl`): keys as the field names above, the extent as
/// {"min": [x, y], "max": [x, y]} or null.
std::string to_json_text(const ImportReport& report);

}  // namespace wm::apriori
