#include "server/service/map_quality_report.h"

#include <algorithm>
#include <limits>
#include <vector>

namespace wm::service {
namespace {

constexpr double kChi2Gate95 = 5.991;  // χ²(2 dof), 95 %

}  // namespace

MapQualityReport measure_map_quality(MapPort& map, const GridPort& grid, const MapQualityReportOptions& options) {
  MapQualityReport report;
  const auto state = map.snapshot();
  report.map_version = state->version;

  std::vector<fusion::LineSegment> elements;
  elements.reserve(state->elements.size());
  for (const auto& [number, element] : state->elements) elements.push_back(element.segment);

  if (const auto bounds = grid.grid_bounds()) {
    const auto layer = grid.grid_layer(fusion::GridLayer::bayes, *bounds);
    report.grid_revision = layer.revision;
    report.map = fusion::map_quality(elements, *bounds, layer.values, options.map);
  } else {
    // No grid yet: the extent figures still mean something; precision and recall have nothing to compare with.
    const fusion::GridGeometry unknown(Eigen::Vector2d::Zero(), 1.0, 1, 1);
    const float unknown_cell[1] = {std::numeric_limits<float>::quiet_NaN()};
    report.map = fusion::map_quality(elements, unknown, unknown_cell, options.map);
  }

  const std::int64_t since =
      std::max<std::int64_t>(0, state->last_decision_seq - static_cast<std::int64_t>(options.calibration_window));
  std::size_t passed = 0;
  for (const auto& d : map.decisions(since, options.calibration_window, std::nullopt)) {
    // Scan lines against observed elements only: a CAD edge's covariance is the drawing's, not something fused.
    if (d.origin != "scan" || !d.mahalanobis_sq || !d.matched_element || d.matched_object) continue;
    ++report.calibration_samples;
    if (*d.mahalanobis_sq <= kChi2Gate95) ++passed;
  }
  if (report.calibration_samples > 0)
    report.calibration = static_cast<double>(passed) / static_cast<double>(report.calibration_samples);
  return report;
}

}  // namespace wm::service
