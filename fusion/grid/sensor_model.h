#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <numbers>
#include <optional>
#include <vector>

#include "fusion/grid/grid_geometry.h"
#include "fusion/grid/scan.h"

namespace wm::fusion {

/// Inverse sensor models for the occupancy grids (seed paper §3, docs/fusion.md §1 and §5), shared by the Bayes and
/// the Dempster–Shafer update. Every field is used; validate() checks them all once.
///
/// Geometry of a beam: a cone (wedge) with its apex at the sensor, aperture laser_beam_width_rad (laser) or the
/// scan's beam_width_rad (sonar). A cell belongs to the cone when its square meets the wedge and its centre is
/// within the walked distance, so a wide cone covers every cell it touches, near the apex too; a zero-width beam
/// covers the DDA line of its axis (one cell per column, 8-connected). Along the beam, with d the distance from
/// the sensor to the cell centre, r the reading, σ the reading's standard deviation and h = max(σ, cell/2) the
/// half-thickness of the return:
///  - free:  d < r − h (up to the clearing distance when there is no return);
///  - hit:   |d − r| <= h, and always the cell containing the return point (so quantisation never loses a
///           return); cells behind r + h are not touched.
/// Sonar: free and hit over the whole cone, uniform in angle (Moravec–Elfes). Laser: the return over the whole
/// cone, weighted by a Gaussian beam profile whose ±2σ_a is the aperture (weight w = exp(−δ²/(2σ_a²)), δ the angle
/// between the axis and the cell centre less the cell's own angular half-size, so cells the axis runs through and
/// the return cell get w = 1); free space only on the axis line. Why: with 2° beams at 1° or 0.5° spacing, a free
/// cone reaches past an obliquely seen wall on its near side by up to r·tan(incidence)·aperture/2 and erodes it;
/// on the Intel log (5 cm) that cut the share of returns within one cell of an occupied cell from 0.955 (thin
/// rays) to 0.895, while hits over the cone with free space on the axis give 0.970.
/// The occupancy in range is the paper's Gaussian P_o = f(r, σ): g(d) = exp(−(d − r)²/(2σ_e²)) with
/// σ_e² = σ² + (cell/2)² (the range noise widened by half a cell, so the Gaussian is not sampled between cell
/// centres), g = 1 at the return cell.
///  - Bayes (Elfes): log-odds increment w·logit(p), p = 0.5 + (p_hit − 0.5)·g for hits, p = p_miss for free.
///  - Dempster–Shafer, eq. (1) discounted by w: P_o = occupied_mass·g, m(O) = w·P_o, m(E) = w·k·(1 − P_o) in front
///    of the reading (d <= r, or no return) and 0 behind it, m(Θ) = 1 − m(O) − m(E).
struct SensorModelOptions {
  double laser_beam_width_rad = 2.0 * std::numbers::pi / 180.0;  // laser aperture, 2° (paper) [rad], [0, π/2)
  double p_hit = 0.7;              // Bayes, laser: occupied evidence at the return (OctoMap default), (0.5, 1)
  double p_miss = 0.4;             // Bayes, laser: free evidence along the beam (OctoMap default), (0, 0.5)
  double sonar_p_hit = 0.6;        // Bayes, sonar: weaker than the laser (the arc only says "somewhere here"), (0.5, 1)
  double sonar_p_miss = 0.45;      // Bayes, sonar: specular reflections make free space less certain, (0, 0.5)
  double ds_empty_factor_k = 0.9;  // DS: P_e = k·(1 − P_o) along the beam, [0, 1)
  double ds_laser_occupied_mass = 0.9;  // DS: peak m(O) of a laser return; the rest stays unknown, (0, 1)
  double ds_sonar_occupied_mass = 0.5;  // DS: peak m(O) of a sonar arc cell, (0, 1)
  double sonar_sigma_per_range = 0.01;  // sonar σ = scan σ + this × reading (docs/fusion.md §5: ±1 %) [m/m], >= 0
  /// Longest distance a beam is walked [m] (OctoMap's maxrange, GMapping's maxUrange): a reading beyond it, or
  /// a "no return", clears free space up to it without marking a hit. Bounds the cost of a beam and keeps
  /// 80 m "no return" codes of old SICK logs from wiping whole buildings. > 0, finite.
  double max_usable_range_m = 20.0;
};

/// @throw std::invalid_argument naming the first field outside its range (see SensorModelOptions).
void validate(const SensorModelOptions& options);

/// One beam of a scan resolved into the world frame with its model parameters.
struct Beam {
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();  // sensor position, world [m]
  double angle_rad = 0.0;                              // direction of the cone's axis, world [rad]
  double half_width_rad = 0.0;                         // half the aperture [rad], [0, π/4)
  double angular_sigma_rad = 0.0;  // σ of a Gaussian beam profile in angle [rad]; 0: uniform over the cone
  bool free_on_axis_only = false;  // free space only on the axis line; the cone only marks the return
  double range_m = 0.0;            // the reading when has_return, else the distance cleared [m]
  bool has_return = false;         // false: free space up to range_m, no hit
  double sigma_m = 0.0;            // range standard deviation of this reading [m]
  double p_hit = 0.7;              // Bayes inverse model at the return
  double p_miss = 0.4;             // Bayes inverse model along the beam
  double occupied_mass = 0.9;      // DS peak m(O)
  double empty_factor_k = 0.9;     // DS k
};

/// How far the beams of this scan are walked [m]: the laser scan's own usable_range_m when it gives one, else
/// options.max_usable_range_m (always for sonar).
double usable_range_m(const LaserScan& scan, const SensorModelOptions& options);
double usable_range_m(const SonarScan& scan, const SensorModelOptions& options);
/// How the range σ grows with range [m/m]: the laser scan's sigma_range_per_m, sonar_sigma_per_range for sonar.
double range_sigma_per_m(const LaserScan& scan, const SensorModelOptions& options);
double range_sigma_per_m(const SonarScan& scan, const SensorModelOptions& options);

/// Beam i of a laser scan (its axis at sensor θ + angle_min + i·increment), or nullopt when the reading is
/// ignored (NaN, negative, below range_min). A reading >= range_max (also +inf) or beyond the usable range
/// (usable_range_m above) becomes a beam without return that clears up to min(range_max, usable range). Its σ is
/// sigma_range_m + sigma_range_per_m · reading.
/// Does not validate scan or options (the caller has). @throw std::out_of_range when i >= ranges_m.size().
std::optional<Beam> laser_beam(const LaserScan& scan, std::size_t i, const SensorModelOptions& options);
/// Beam i of a sonar ring; σ = sigma_range_m + sonar_sigma_per_range·reading. Otherwise as laser_beam.
std::optional<Beam> sonar_beam(const SonarScan& scan, std::size_t i, const SensorModelOptions& options);

/// What one beam says about one cell.
struct BeamCell {
  CellIndex cell;               // in a grid whose cell (0, 0) has its lower-left corner at the world origin
  bool hit = false;             // in the return band (or the return cell) rather than free space
  double distance_m = 0.0;      // sensor to cell centre [m]
  double bayes_log_odds = 0.0;  // Bayes increment w·logit(p)
  double m_occupied = 0.0;      // DS masses of eq. (1); m(Θ) = 1 − m_occupied − m_empty
  double m_empty = 0.0;
};

/// Every cell the beam touches, with its evidence, in walk order (outward from the sensor, each cell once). The
/// grid runs the same walk without allocating; this is the testable, inspectable form of it.
/// @throw std::invalid_argument when resolution_m is not in (0, 100] or the beam is not finite / its half width
///        not in [0, π/4).
std::vector<BeamCell> beam_cells(const Beam& beam, double resolution_m);

}  // namespace wm::fusion
