#include "fusion/grid/sensor_model.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fusion/grid/internal/beam_walk.h"

namespace wm::fusion {
namespace {

void require(bool ok, const char* field, const char* range) {
  if (!ok) throw std::invalid_argument(std::string("validate(SensorModelOptions): ") + field + " must be " + range);
}

// Shared by laser and sonar: ignore, clear or return.
std::optional<Beam> make_beam(double reading, double range_min, double range_max, double usable_range) {
  // Negated comparison so NaN is ignored as well.
  if (!(reading >= 0.0 && reading >= range_min)) return std::nullopt;
  Beam beam;
  const double clear_to = std::min(range_max, usable_range);
  if (reading >= range_max || reading > usable_range) {
    beam.has_return = false;
    beam.range_m = clear_to;
  } else {
    beam.has_return = true;
    beam.range_m = reading;
  }
  return beam;
}

}  // namespace

void validate(const SensorModelOptions& o) {
  require(o.laser_beam_width_rad >= 0.0 && o.laser_beam_width_rad < kMaxBeamWidthRad, "laser_beam_width_rad",
          "in [0, pi/2)");
  require(o.p_hit > 0.5 && o.p_hit < 1.0, "p_hit", "in (0.5, 1)");
  require(o.p_miss > 0.0 && o.p_miss < 0.5, "p_miss", "in (0, 0.5)");
  require(o.sonar_p_hit > 0.5 && o.sonar_p_hit < 1.0, "sonar_p_hit", "in (0.5, 1)");
  require(o.sonar_p_miss > 0.0 && o.sonar_p_miss < 0.5, "sonar_p_miss", "in (0, 0.5)");
  require(o.ds_empty_factor_k >= 0.0 && o.ds_empty_factor_k < 1.0, "ds_empty_factor_k", "in [0, 1)");
  require(o.ds_laser_occupied_mass > 0.0 && o.ds_laser_occupied_mass < 1.0, "ds_laser_occupied_mass", "in (0, 1)");
  require(o.ds_sonar_occupied_mass > 0.0 && o.ds_sonar_occupied_mass < 1.0, "ds_sonar_occupied_mass", "in (0, 1)");
  require(o.sonar_sigma_per_range >= 0.0 && std::isfinite(o.sonar_sigma_per_range), "sonar_sigma_per_range",
          "finite and >= 0");
  require(o.max_usable_range_m > 0.0 && std::isfinite(o.max_usable_range_m), "max_usable_range_m", "finite and > 0");
}

double usable_range_m(const LaserScan& scan, const SensorModelOptions& options) {
  return scan.usable_range_m > 0.0 ? scan.usable_range_m : options.max_usable_range_m;
}
double usable_range_m(const SonarScan&, const SensorModelOptions& options) { return options.max_usable_range_m; }
double range_sigma_per_m(const LaserScan& scan, const SensorModelOptions&) { return scan.sigma_range_per_m; }
double range_sigma_per_m(const SonarScan&, const SensorModelOptions& options) { return options.sonar_sigma_per_range; }

std::optional<Beam> laser_beam(const LaserScan& scan, std::size_t i, const SensorModelOptions& options) {
  if (i >= scan.ranges_m.size()) throw std::out_of_range("laser_beam: beam index out of range");
  auto beam = make_beam(scan.ranges_m[i], scan.range_min_m, scan.range_max_m, usable_range_m(scan, options));
  if (!beam) return beam;
  beam->origin_m = {scan.sensor_pose.x_m, scan.sensor_pose.y_m};
  beam->angle_rad = scan.sensor_pose.theta_rad + scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
  beam->half_width_rad = 0.5 * options.laser_beam_width_rad;
  beam->angular_sigma_rad = 0.25 * options.laser_beam_width_rad;  // the aperture is ±2σ_a
  beam->free_on_axis_only = true;
  beam->sigma_m = scan.sigma_range_m + scan.sigma_range_per_m * beam->range_m;
  beam->p_hit = options.p_hit;
  beam->p_miss = options.p_miss;
  beam->occupied_mass = options.ds_laser_occupied_mass;
  beam->empty_factor_k = options.ds_empty_factor_k;
  return beam;
}

std::optional<Beam> sonar_beam(const SonarScan& scan, std::size_t i, const SensorModelOptions& options) {
  if (i >= scan.ranges_m.size() || i >= scan.angles_rad.size()) {
    throw std::out_of_range("sonar_beam: beam index out of range");
  }
  auto beam = make_beam(scan.ranges_m[i], scan.range_min_m, scan.range_max_m, usable_range_m(scan, options));
  if (!beam) return beam;
  beam->origin_m = {scan.sensor_pose.x_m, scan.sensor_pose.y_m};
  beam->angle_rad = scan.sensor_pose.theta_rad + scan.angles_rad[i];
  beam->half_width_rad = 0.5 * scan.beam_width_rad;
  beam->sigma_m = scan.sigma_range_m + options.sonar_sigma_per_range * beam->range_m;
  beam->p_hit = options.sonar_p_hit;
  beam->p_miss = options.sonar_p_miss;
  beam->occupied_mass = options.ds_sonar_occupied_mass;
  beam->empty_factor_k = options.ds_empty_factor_k;
  return beam;
}

std::vector<BeamCell> beam_cells(const Beam& beam, double resolution_m) {
  if (!(resolution_m > 0.0 && resolution_m <= GridGeometry::kMaxResolutionM)) {
    throw std::invalid_argument("beam_cells: resolution_m must be in (0, 100]");
  }
  if (!beam.origin_m.allFinite() || !std::isfinite(beam.angle_rad) || !std::isfinite(beam.range_m) ||
      !std::isfinite(beam.sigma_m) || !std::isfinite(beam.angular_sigma_rad) || beam.range_m < 0.0 ||
      beam.sigma_m < 0.0 || beam.angular_sigma_rad < 0.0) {
    throw std::invalid_argument("beam_cells: beam must be finite, with range_m, sigma_m, angular_sigma_rad >= 0");
  }
  if (!(beam.half_width_rad >= 0.0 && beam.half_width_rad < 0.5 * kMaxBeamWidthRad)) {
    throw std::invalid_argument("beam_cells: half_width_rad must be in [0, pi/4)");
  }
  const internal::PreparedBeam b = internal::prepare(beam, resolution_m);
  std::vector<BeamCell> cells;
  internal::for_each_beam_cell(b, [&](std::int64_t x, std::int64_t y, double d2, internal::CellClass cls) {
    const double d = std::sqrt(d2);
    const double g = internal::range_factor(b, cls, x, y, d);
    const double w = internal::angular_weight(b, x, y, d2);
    const internal::CellMasses m = internal::ds_masses(b, g, d, w);
    BeamCell cell;
    cell.cell = {x, y};
    cell.hit = cls == internal::CellClass::hit;
    cell.distance_m = d * resolution_m;
    cell.bayes_log_odds = w * (cell.hit ? internal::bayes_hit_log_odds(b, g) : b.log_odds_miss);
    cell.m_occupied = m.occupied;
    cell.m_empty = m.empty;
    cells.push_back(cell);
  });
  return cells;
}

}  // namespace wm::fusion
