#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>

#include "fusion/quality/map_quality.h"
#include "server/service/world_port.h"

namespace wm::service {

/// What GET /api/v1/map/quality reports: the vector map scored against the current Bayes grid, and how honest the
/// elements' covariances are.
struct MapQualityReport {
  fusion::MapQuality map;
  /// Share of recent scan lines matched to an observed element whose normalised innovation d² = Δᵀ(Ce+Co)⁻¹Δ passes
  /// the 95 % χ²(2) gate (5.991). Honest covariances give about 0.95; far below means over-confident elements,
  /// far above over-cautious ones. nullopt when no such line is in the window.
  std::optional<double> calibration;
  std::size_t calibration_samples = 0;  // matched scan lines it was computed from
  std::int64_t map_version = 0;
  std::int64_t grid_revision = 0;
};

struct MapQualityReportOptions {
  fusion::MapQualityOptions map;
  std::size_t calibration_window = 20000;  // the last this many decisions are looked at
};

/// Scores the current map (elements only; CAD edges are the reference, not the product) against its Bayes
/// grid, and the calibration from the decision log. @throw storage::StorageError from the decision log.
MapQualityReport measure_map_quality(MapPort& map, const GridPort& grid, const MapQualityReportOptions& options = {});

}  // namespace wm::service
