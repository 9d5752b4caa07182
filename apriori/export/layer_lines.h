#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace wm::apriori {

/// Generic input of the plan exporters: named layers of world-frame polylines [m].
/// A closed outline repeats its first point at the end.
struct LayerLines {
  std::string layer;                                      // e.g. "confirmed", "merged", "adjusted", "new"
  std::vector<std::vector<Eigen::Vector2d>> polylines{};  // each with at least 2 points [m]
  /// Optional, empty or one per polyline: the id of what each polyline draws (object or element id). GeoJSON
  /// writes it as the feature's "id" and "id" property; the DXF writer ignores it.
  std::vector<std::string> ids{};
  /// AutoCAD colour index 1..255 of the layer in DXF (7 = white/black); GeoJSON writes it as property "color".
  int color = 7;
};

/// The name the brief of the map export used; the same type.
using DxfLayerLines = LayerLines;

}  // namespace wm::apriori
