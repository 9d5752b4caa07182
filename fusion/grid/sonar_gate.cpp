#include "fusion/grid/sonar_gate.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace wm::fusion {
namespace {

double logit(double p) { return std::log(p / (1.0 - p)); }

}  // namespace

void validate(const SonarGateOptions& options) {
  const auto check = [](bool ok, const char* field, const char* range) {
    if (!ok) throw std::invalid_argument(std::string("SonarGateOptions::") + field + " must be " + range);
  };
  check(options.free_probability > 0 && options.free_probability < 0.5, "free_probability", "in (0, 0.5)");
  check(options.occupied_probability > 0.5 && options.occupied_probability < 1, "occupied_probability", "in (0.5, 1)");
  check(options.phantom_seen_share > 0 && options.phantom_seen_share <= 1, "phantom_seen_share", "in (0, 1]");
  check(std::isfinite(options.band_margin_m) && options.band_margin_m >= 0 && options.band_margin_m <= 10,
        "band_margin_m", "in [0, 10]");
  check(std::isfinite(options.clip_margin_m) && options.clip_margin_m >= 0 && options.clip_margin_m <= 10,
        "clip_margin_m", "in [0, 10]");
}

const char* to_string(SonarVerdict verdict) {
  switch (verdict) {
    case SonarVerdict::kept:
      return "kept";
    case SonarVerdict::unjudged:
      return "unjudged";
    case SonarVerdict::phantom:
      return "phantom";
    case SonarVerdict::clipped:
      return "clipped";
    case SonarVerdict::ignored:
      return "ignored";
  }
  return "?";
}

std::size_t SonarGateResult::count(SonarVerdict verdict) const {
  return static_cast<std::size_t>(std::count(verdicts.begin(), verdicts.end(), verdict));
}

SonarGateResult gate_sonar(const SonarScan& scan, const OccupancyGrid& laser_grid, const SonarGateOptions& options,
                           const std::vector<Eigen::Vector2d>& recent_returns) {
  validate(scan);
  validate(options);
  const auto& sensor = laser_grid.options().sensor;
  const double resolution = laser_grid.resolution_m();
  const double free = logit(options.free_probability);
  const double occupied = logit(options.occupied_probability);
  OccupancyGrid::CellReader laser(laser_grid);
  SonarGateResult result;
  result.beams.reserve(scan.ranges_m.size());
  result.verdicts.reserve(scan.ranges_m.size());
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    auto beam = sonar_beam(scan, i, sensor);
    if (!beam) {
      result.beams.emplace_back();
      result.verdicts.push_back(SonarVerdict::ignored);
      continue;
    }
    auto verdict = SonarVerdict::kept;
    if (beam->has_return) {
      // The return's arc, widened: does the laser have anything there?
      Beam band = *beam;
      band.sigma_m = beam->sigma_m + options.band_margin_m;
      std::size_t cells = 0, seen_free = 0;
      bool backed = false;
      for (const auto& cell : beam_cells(band, resolution)) {
        if (!cell.hit) continue;
        ++cells;
        const double l = laser.log_odds(cell.cell);
        if (l > occupied) {
          backed = true;
          break;
        }
        if (l < free) ++seen_free;
      }
      for (std::size_t k = 0; !backed && k < recent_returns.size(); ++k) {
        const Eigen::Vector2d v = recent_returns[k] - beam->origin_m;
        const double d = v.norm();
        if (std::abs(d - beam->range_m) > band.sigma_m + resolution) continue;
        const double off_axis =
            std::abs(std::remainder(std::atan2(v.y(), v.x()) - beam->angle_rad, 2 * std::numbers::pi));
        backed = off_axis <= beam->half_width_rad + std::atan2(options.band_margin_m, std::max(d, 1e-3));
      }
      if (!backed) {
        if (cells > 0 && static_cast<double>(seen_free) >= options.phantom_seen_share * static_cast<double>(cells)) {
          result.beams.emplace_back();
          result.verdicts.push_back(SonarVerdict::phantom);
          continue;
        }
        verdict = SonarVerdict::unjudged;
      }
    }
    // The cone's free space (in walk order, outward): does it run into a surface the laser sees?
    const double half_thickness = std::max(beam->sigma_m, resolution / 2);
    const double free_end = beam->has_return ? beam->range_m - half_thickness : beam->range_m;
    double first_surface = free_end;
    for (const auto& cell : beam_cells(*beam, resolution)) {
      if (cell.hit || cell.distance_m >= first_surface) continue;
      if (laser.log_odds(cell.cell) > occupied) first_surface = cell.distance_m;
    }
    if (first_surface < free_end - options.band_margin_m) {  // a surface within the band is the echo's own
      const double clear_to = first_surface - resolution / 2 - options.clip_margin_m;
      if (clear_to > resolution) {
        beam->has_return = false;
        beam->range_m = clear_to;
        result.beams.push_back(beam);
      } else {
        result.beams.emplace_back();
      }
      result.verdicts.push_back(SonarVerdict::clipped);
      continue;
    }
    result.beams.push_back(beam);
    result.verdicts.push_back(verdict);
  }
  return result;
}

}  // namespace wm::fusion
