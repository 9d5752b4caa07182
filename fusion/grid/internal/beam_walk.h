#pragma once

// The beam walk shared by beam_cells() and OccupancyGrid::insert(): header-only so the per-cell callback
// inlines into the grid's update loop (no std::function, no allocation per beam).
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "fusion/grid/sensor_model.h"

namespace wm::fusion::internal {

/// Calls visit(cx, cy, d2) once for every cell whose square meets the wedge {origin + t·(cos α, sin α): t >= 0,
/// |α − angle| <= half_width} and whose centre is within `limit` of the origin; d2 is that centre's squared
/// distance. Everything is in cell units (world / resolution), cell (i, j) spanning [i, i+1) × [j, j+1).
///
/// A column DDA: it steps one cell at a time along the beam's major axis (the one closer to its direction) and,
/// per column, takes the rows the wedge spans over that column strip, clipped to the circle of radius `limit`.
/// For a zero-width wedge that is the supercover of the axis. Requires half_width in [0, π/4), so both edges
/// stay within 90° of the major axis and each column's span is an interval.
template <typename Visit>
void walk_cone(double ox, double oy, double angle_rad, double half_width_rad, double limit, Visit&& visit) {
  const double c = std::cos(angle_rad);
  const double s = std::sin(angle_rad);
  const bool x_major = std::abs(c) >= std::abs(s);
  const double ou = x_major ? ox : oy;
  const double ov = x_major ? oy : ox;
  const double dir = (x_major ? c : s) >= 0.0 ? 1.0 : -1.0;
  // dv per unit of forward travel along the major axis, for both wedge edges.
  const auto slope = [&](double a) {
    const double cu = x_major ? std::cos(a) : std::sin(a);
    const double cv = x_major ? std::sin(a) : std::cos(a);
    return cv / (cu * dir);
  };
  const double m1 = slope(angle_rad - half_width_rad);
  const double m2 = slope(angle_rad + half_width_rad);
  const double m_lo = std::min(m1, m2);
  const double m_hi = std::max(m1, m2);
  const double limit2 = limit * limit;
  const std::int64_t step = dir > 0.0 ? 1 : -1;

  for (auto i = static_cast<std::int64_t>(std::floor(ou));; i += step) {
    const double lo_edge = static_cast<double>(i);
    const double near_edge = dir > 0.0 ? lo_edge : lo_edge + 1.0;
    const double far_edge = dir > 0.0 ? lo_edge + 1.0 : lo_edge;
    const double ta = std::max(0.0, (near_edge - ou) * dir);  // forward distance of the strip, clipped at the apex
    const double tb = (far_edge - ou) * dir;
    const double tc = lo_edge + 0.5 - ou;  // signed offset of the column's centres
    const double tc2 = tc * tc;
    // Past the apex column the centres only move away, so the first column beyond the circle ends the walk.
    if (ta > 0.0 && tc2 > limit2) break;
    const double reach = std::sqrt(std::max(0.0, limit2 - tc2));
    // Clamp before floor(): a near-vertical edge has a huge slope.
    const double v_min = std::max(ov + (m_lo >= 0.0 ? ta : tb) * m_lo, ov - reach - 1.0);
    const double v_max = std::min(ov + (m_hi >= 0.0 ? tb : ta) * m_hi, ov + reach + 1.0);
    const auto j_lo = static_cast<std::int64_t>(std::max(std::floor(v_min), std::ceil(ov - reach - 0.5)));
    const auto j_hi = static_cast<std::int64_t>(std::min(std::floor(v_max), std::floor(ov + reach - 0.5)));
    for (std::int64_t j = j_lo; j <= j_hi; ++j) {
      const double dv = static_cast<double>(j) + 0.5 - ov;
      const double d2 = tc2 + dv * dv;
      if (d2 > limit2) continue;
      if (x_major) {
        visit(i, j, d2);
      } else {
        visit(j, i, d2);
      }
    }
  }
}

/// A Beam converted to cell units with its classification thresholds (see SensorModelOptions).
struct PreparedBeam {
  double ox = 0, oy = 0;       // origin [cells]
  double angle_rad = 0, half_width_rad = 0;
  double r = 0;                // reading or clearing distance [cells]
  bool has_return = false;
  double free_limit2 = 0;      // d² < this: free [cells²]
  double hit_limit2 = 0;       // d² <= this: hit [cells²]
  double walk_limit = 0;       // cells with centres farther than this are not visited [cells]
  std::int64_t end_x = 0, end_y = 0;  // the cell containing the return point
  double inv_two_sigma_e2 = 0;  // 1 / (2σ_e²) [1/cells²]
  double gaussian_reach = 0;    // beyond 4σ_e in front of the return g is taken as 0 [cells]
  double tail_limit2 = -1;      // d² <= this: in front of the Gaussian's reach, g = 0 without a sqrt [cells²]
  double ux = 1, uy = 0;        // axis direction
  double inv_two_sigma_a2 = 0;  // 1 / (2σ_a²) of the angular profile [1/rad²]; 0: uniform in angle
  double p_hit = 0, log_odds_miss = 0;
  double occupied_mass = 0, k = 0;
};

inline double logit(double p) { return std::log(p / (1.0 - p)); }

inline PreparedBeam prepare(const Beam& beam, double resolution_m) {
  PreparedBeam b;
  const double inv = 1.0 / resolution_m;
  b.ox = beam.origin_m.x() * inv;
  b.oy = beam.origin_m.y() * inv;
  b.angle_rad = beam.angle_rad;
  b.half_width_rad = beam.half_width_rad;
  b.r = beam.range_m * inv;
  b.has_return = beam.has_return;
  const double sigma = beam.sigma_m * inv;
  const double h = std::max(sigma, 0.5);
  if (beam.has_return) {
    b.free_limit2 = b.r > h ? (b.r - h) * (b.r - h) : -1.0;
    b.hit_limit2 = (b.r + h) * (b.r + h);
    // The return cell's centre can lie up to half a diagonal behind r.
    b.walk_limit = b.r + std::max(h, 0.7072);
    const double ex = b.ox + b.r * std::cos(beam.angle_rad);
    const double ey = b.oy + b.r * std::sin(beam.angle_rad);
    b.end_x = static_cast<std::int64_t>(std::floor(ex));
    b.end_y = static_cast<std::int64_t>(std::floor(ey));
  } else {
    b.free_limit2 = b.r * b.r * (1.0 + 1e-12);  // everything walked is free
    b.hit_limit2 = b.free_limit2;
    b.walk_limit = b.r;
  }
  const double sigma_e2 = sigma * sigma + 0.25;
  b.inv_two_sigma_e2 = 1.0 / (2.0 * sigma_e2);
  b.gaussian_reach = 4.0 * std::sqrt(sigma_e2);
  if (b.has_return && b.r > b.gaussian_reach) b.tail_limit2 = (b.r - b.gaussian_reach) * (b.r - b.gaussian_reach);
  b.ux = std::cos(beam.angle_rad);
  b.uy = std::sin(beam.angle_rad);
  if (beam.angular_sigma_rad > 0.0) b.inv_two_sigma_a2 = 1.0 / (2.0 * beam.angular_sigma_rad * beam.angular_sigma_rad);
  b.p_hit = beam.p_hit;
  b.log_odds_miss = logit(beam.p_miss);
  b.occupied_mass = beam.occupied_mass;
  b.k = beam.empty_factor_k;
  return b;
}

enum class CellClass : std::uint8_t { skip, free, hit };

/// Free, hit, or not part of the beam (behind the return band), for a visited cell.
inline CellClass classify(const PreparedBeam& b, std::int64_t cx, std::int64_t cy, double d2) {
  if (b.has_return && cx == b.end_x && cy == b.end_y) return CellClass::hit;
  if (d2 < b.free_limit2) return CellClass::free;
  if (b.has_return && d2 <= b.hit_limit2) return CellClass::hit;
  return CellClass::skip;
}

/// The Gaussian range factor g of a cell at distance d [cells]: 1 at the return cell, 0 without a return or
/// more than 4σ_e in front of it.
inline double range_factor(const PreparedBeam& b, CellClass cls, std::int64_t cx, std::int64_t cy, double d) {
  if (!b.has_return) return 0.0;
  if (cls == CellClass::hit && cx == b.end_x && cy == b.end_y) return 1.0;
  const double e = d - b.r;
  if (-e > b.gaussian_reach) return 0.0;
  return std::exp(-e * e * b.inv_two_sigma_e2);
}

/// The angular weight w of a cell with squared centre distance d2 [cells²]: 1 for a uniform cone, for the return
/// cell and for cells the axis runs through (lateral offset of the centre <= half a cell); otherwise the Gaussian
/// beam profile exp(−δ²/(2σ_a²)) at δ = (lateral offset − half a cell)/d, small-angle.
inline double angular_weight(const PreparedBeam& b, std::int64_t cx, std::int64_t cy, double d2) {
  if (b.inv_two_sigma_a2 == 0.0) return 1.0;
  const double dx = static_cast<double>(cx) + 0.5 - b.ox;
  const double dy = static_cast<double>(cy) + 0.5 - b.oy;
  const double lateral = std::abs(dx * b.uy - dy * b.ux) - 0.5;
  if (lateral <= 0.0 || (b.has_return && cx == b.end_x && cy == b.end_y)) return 1.0;
  return std::exp(-lateral * lateral / std::max(d2, 0.25) * b.inv_two_sigma_a2);
}

inline double bayes_hit_log_odds(const PreparedBeam& b, double g) { return logit(0.5 + (b.p_hit - 0.5) * g); }

struct CellMasses {
  double occupied, empty;
};

/// Eq. (1), discounted by the angular weight w: m(O) = w·peak·g, m(E) = w·k·(1 − peak·g) in front of the
/// reading, 0 behind it.
inline CellMasses ds_masses(const PreparedBeam& b, double g, double d, double w) {
  const double p_o = b.occupied_mass * g;
  const bool in_front = !b.has_return || d <= b.r;
  return {w * p_o, in_front ? w * b.k * (1.0 - p_o) : 0.0};
}

}  // namespace wm::fusion::internal
