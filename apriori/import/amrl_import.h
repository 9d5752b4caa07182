#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "apriori/floor_plan.h"
#include "apriori/import/import_report.h"

namespace wm::apriori {

/// Options of import_amrl_vectormap.
struct AmrlImportOptions {
  std::string kind = "wall";
  std::vector<std::string> attributes{"solid"};
  /// Segments shorter than this are skipped (the maps hold a few zero-length strokes) [m].
  double min_length_m = 1e-3;
  std::string name = "amrl vector map";
  FloorPlanLimits limits;
};

/// Converts a UT Austin AMRL vector map into a floor plan: one object per wall segment ("wall-<i>", i = index in
/// the file), posed at the segment's middle. Accepts the JSON form, `[{"p0": {"x": .., "y": ..}, "p1": {...}}, ...]`
/// in metres, and the text form `x0, y0, x1, y1` per line (`*.vectormap.txt`; blank lines and '#' comments ignored).
/// @throw FloorPlanError with the path of the bad value ("[12].p1.y", "line 7"), for absurd coordinates too.
/// @throw std::invalid_argument for a negative or non-finite min_length_m.
ImportResult import_amrl_vectormap(std::string_view text, const AmrlImportOptions& options = {});

}  // namespace wm::apriori
