#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>

#include "apriori/floor_plan.h"
#include "server/service/map_quality_report.h"
#include "server/service/world_service.h"

namespace wm::replay {

struct LogReplayOptions {
  std::filesystem::path rules_dir;  // the knowledge base's rule files
  std::filesystem::path work_dir;   // the SQLite file goes here; must exist
  service::ServiceOptions service;  // the world service's settings (grid, matching, scan lines)
  /// The pose uncertainty every scan is posted with, as `wmctl replay` does: corrected poses are good, not exact.
  double sigma_xy_m = 0.03;
  double sigma_theta_rad = 0.0087;
  std::size_t every = 1;      // replay every K-th scan
  std::size_t max_scans = 0;  // 0: all
  /// Loaded before the first scan (e.g. to measure what a large plan costs ingest).
  std::optional<apriori::FloorPlan> plan;
};

struct LogReplayResult {
  std::size_t scans = 0;
  double seconds = 0;  // wall time of the replay (not of the scoring)
  service::MapQualityReport quality;
};

/// Replays a CARMEN log (plain or gzip) scan by scan through WorldService::post_scan — the same path as
/// POST /api/v1/scans, minus HTTP — then scores the map. `on_service` (optional) sees the service after the
/// replay, before it is torn down. @throw logs::LogError, and whatever the service throws.
LogReplayResult replay_log(const std::filesystem::path& log, const LogReplayOptions& options,
                           const std::function<void(service::WorldService&)>& on_service = {});

}  // namespace wm::replay
