#pragma once

// The beam walk shared by beam_cells() and OccupancyGrid::insert(): header-only so the per-cell callback
// inlines into the grid's update loop (no std::function, no allocation per beam).
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "fusion/grid/sensor_model.h"

namespace wm::fusion::internal {

/// floor() as an integer without a libm call (x86-64's baseline has no SSE4.1 round instruction); |x| < 2^62.
inline std::int64_t floor_to_int(double x) {
  const auto i = static_cast<std::int64_t>(x);  // truncates towards zero
  return i - (static_cast<double>(i) > x ? 1 : 0);
}

/// A Beam converted to cell units with its classification thresholds (see SensorModelOptions).
struct PreparedBeam {
  double ox = 0, oy = 0;  // origin [cells]
  double angle_rad = 0, half_width_rad = 0;
  double r = 0;  // reading or clearing distance [cells]
  bool has_return = false;
  bool free_on_axis_only = false;     // free space only on the axis line, the cone only for the return
  double free_limit2 = 0;             // d² < this: free [cells²]
  double hit_limit2 = 0;              // d² <= this: hit [cells²]
  double walk_limit = 0;              // cells with centres farther than this are not visited [cells]
  double hit_min_distance = 0;        // no hit cell meets the wedge closer than this to the origin [cells]
  std::int64_t end_x = 0, end_y = 0;  // the cell containing the return point
  double inv_two_sigma_e2 = 0;        // 1 / (2σ_e²) [1/cells²]
  double gaussian_reach = 0;          // beyond 4σ_e in front of the return g is taken as 0 [cells]
  double tail_limit2 = -1;            // d² <= this: in front of the Gaussian's reach, g = 0 without a sqrt [cells²]
  double ux = 1, uy = 0;              // axis direction
  double cos_half = 1, sin_half = 0;  // of half_width_rad
  double inv_two_sigma_a2 = 0;        // 1 / (2σ_a²) of the angular profile [1/rad²]; 0: uniform in angle
  double p_hit = 0, log_odds_miss = 0;
  double occupied_mass = 0, k = 0;
};

inline double logit(double p) { return std::log(p / (1.0 - p)); }

/// cos_half, sin_half: of beam.half_width_rad, which all beams of a scan share (saves a sincos per beam).
inline PreparedBeam prepare(const Beam& beam, double resolution_m, double cos_half, double sin_half) {
  PreparedBeam b;
  const double inv = 1.0 / resolution_m;
  b.ox = beam.origin_m.x() * inv;
  b.oy = beam.origin_m.y() * inv;
  b.angle_rad = beam.angle_rad;
  b.half_width_rad = beam.half_width_rad;
  b.ux = std::cos(beam.angle_rad);
  b.uy = std::sin(beam.angle_rad);
  b.r = beam.range_m * inv;
  b.has_return = beam.has_return;
  b.free_on_axis_only = beam.free_on_axis_only && beam.half_width_rad > 0.0;
  const double sigma = beam.sigma_m * inv;
  const double h = std::max(sigma, 0.5);
  if (beam.has_return) {
    b.free_limit2 = b.r > h ? (b.r - h) * (b.r - h) : -1.0;
    b.hit_limit2 = (b.r + h) * (b.r + h);
    // The return cell's centre can lie up to half a diagonal behind r.
    b.walk_limit = b.r + std::max(h, 0.7072);
    const double ex = b.ox + b.r * b.ux;
    const double ey = b.oy + b.r * b.uy;
    b.end_x = floor_to_int(ex);
    b.end_y = floor_to_int(ey);
  } else {
    b.free_limit2 = b.r * b.r * (1.0 + 1e-12);  // everything walked is free
    b.hit_limit2 = b.free_limit2;
    b.walk_limit = b.r;
  }
  const double sigma_e2 = sigma * sigma + 0.25;
  b.inv_two_sigma_e2 = 1.0 / (2.0 * sigma_e2);
  b.gaussian_reach = 4.0 * std::sqrt(sigma_e2);
  if (b.has_return && b.r > b.gaussian_reach) b.tail_limit2 = (b.r - b.gaussian_reach) * (b.r - b.gaussian_reach);
  b.cos_half = cos_half;
  b.sin_half = sin_half;
  if (beam.angular_sigma_rad > 0.0) b.inv_two_sigma_a2 = 1.0 / (2.0 * beam.angular_sigma_rad * beam.angular_sigma_rad);
  b.hit_min_distance = std::max(0.0, b.r - std::max(h, 0.7072) - 1.0);
  b.p_hit = beam.p_hit;
  b.log_odds_miss = logit(beam.p_miss);
  b.occupied_mass = beam.occupied_mass;
  b.k = beam.empty_factor_k;
  return b;
}

/// Calls visit(cx, cy, d2) once for every cell of the beam b: every cell whose square meets the wedge
/// {origin + t·(cos α, sin α): t >= 0, |α − angle| <= half_width} and whose centre is within b.walk_limit of the
/// origin, d2 being that centre's squared distance. A zero-width beam instead visits one cell per column, the one
/// holding the axis at the column's centre line (a DDA line, like Bresenham's: 8-connected, fewer cells than the
/// supercover), plus every cell the axis crosses in the origin's column and the cell holding the return point.
/// Everything is in cell units, cell (i, j) spanning [i, i+1) × [j, j+1).
///
/// A column DDA: it steps one cell at a time along the beam's major axis (the one closer to its direction) and,
/// per column, takes the rows the wedge spans over that column strip, clipped to the circle of radius walk_limit.
/// Requires half_width in [0, π/4), so both edges stay within 90° of the major axis and each column's span is an
/// interval. No trigonometry and no libm call per column. Wide walks skip the columns that end closer than
/// min_forward [cells] along the major axis.
template <typename Visit>
void walk_cone(const PreparedBeam& b, Visit&& visit, double min_forward = 0.0) {
  const bool x_major = std::abs(b.ux) >= std::abs(b.uy);
  const double ou = x_major ? b.ox : b.oy;
  const double ov = x_major ? b.oy : b.ox;
  const double dir = (x_major ? b.ux : b.uy) >= 0.0 ? 1.0 : -1.0;
  // dv per unit of forward travel along the major axis, for both wedge edges (rotations of the axis by ±half).
  const auto slope = [&](double cx, double cy) { return (x_major ? cy : cx) / ((x_major ? cx : cy) * dir); };
  const double m1 = slope(b.ux * b.cos_half + b.uy * b.sin_half, b.uy * b.cos_half - b.ux * b.sin_half);
  const double m2 = slope(b.ux * b.cos_half - b.uy * b.sin_half, b.uy * b.cos_half + b.ux * b.sin_half);
  const double m_lo = std::min(m1, m2);
  const double m_hi = std::max(m1, m2);
  const bool thin = b.half_width_rad == 0.0;
  const std::int64_t end_u = x_major ? b.end_x : b.end_y;
  const std::int64_t end_v = x_major ? b.end_y : b.end_x;
  const double limit2 = b.walk_limit * b.walk_limit;
  const std::int64_t step = dir > 0.0 ? 1 : -1;

  if (thin) {
    // The apex column: every cell the axis crosses in it, so the line stays 8-connected from the origin.
    const std::int64_t i0 = floor_to_int(ou);
    {
      const double lo_edge = static_cast<double>(i0);
      const double tc = lo_edge + 0.5 - ou;
      const double tb = dir > 0.0 ? lo_edge + 1.0 - ou : ou - lo_edge;
      const std::int64_t ja = floor_to_int(ov);
      const std::int64_t jb = floor_to_int(ov + tb * m_lo);
      const std::int64_t jstep = jb >= ja ? 1 : -1;
      for (std::int64_t j = ja;; j += jstep) {
        const double dv = static_cast<double>(j) + 0.5 - ov;
        const double d2 = tc * tc + dv * dv;
        if (d2 <= limit2) {
          if (x_major) {
            visit(i0, j, d2);
          } else {
            visit(j, i0, d2);
          }
        }
        if (j == jb) break;
      }
    }
    // Then one cell per column, where the axis crosses the column's centre line (incremental: no per-column
    // conversion of the column index)...
    const double first = (static_cast<double>(i0 + step) + 0.5 - ou) * dir;  // forward distance of that line
    double fwd = first;
    double v = ov + first * m_lo;
    for (std::int64_t i = i0 + step;; i += step, fwd += 1.0, v += m_lo) {
      const double tc2 = fwd * fwd;
      if (tc2 > limit2) break;
      const std::int64_t j = floor_to_int(v);
      const double dv = static_cast<double>(j) + 0.5 - ov;
      const double d2 = tc2 + dv * dv;
      if (d2 <= limit2) {
        if (x_major) {
          visit(i, j, d2);
        } else {
          visit(j, i, d2);
        }
      }
      // ...and the cell holding the return point, which a line can pass by (it may sit in the next row).
      if (b.has_return && i == end_u && j != end_v) {
        const double ev = static_cast<double>(end_v) + 0.5 - ov;
        visit(b.end_x, b.end_y, tc2 + ev * ev);
      }
      if (d2 > limit2) break;
    }
    return;
  }

  // Columns that end before min_forward are skipped outright: column k past the apex column ends at most k + 1 ahead.
  const std::int64_t skip = min_forward > 1.0 ? floor_to_int(min_forward) - 1 : 0;
  for (std::int64_t i = floor_to_int(ou) + step * skip;; i += step) {
    const double lo_edge = static_cast<double>(i);
    const double tc = lo_edge + 0.5 - ou;  // signed offset of the column's centres
    const double tc2 = tc * tc;
    const double near_edge = dir > 0.0 ? lo_edge : lo_edge + 1.0;
    const double ta = std::max(0.0, (near_edge - ou) * dir);  // forward distance of the strip, clipped at the apex
    // Past the apex column the centres only move away, so the first column beyond the circle ends the walk.
    if (ta > 0.0 && tc2 > limit2) break;
    const double tb = ta > 0.0 ? ta + 1.0 : (dir > 0.0 ? lo_edge + 1.0 - ou : ou - lo_edge);
    if (tb < min_forward) continue;
    double v_min = ov + (m_lo >= 0.0 ? ta : tb) * m_lo;
    double v_max = ov + (m_hi >= 0.0 ? tb : ta) * m_hi;
    // Clip to the circle only where it can cut (near the end, or a near-vertical edge): saves a sqrt per column.
    const double spread = std::max(v_max - ov, ov - v_min) + 1.0;
    if (tc2 + spread * spread > limit2) {
      const double reach = std::sqrt(std::max(0.0, limit2 - tc2));
      v_min = std::max(v_min, ov - reach - 0.5);
      v_max = std::min(v_max, ov + reach + 0.5);
    }
    const std::int64_t j_lo = floor_to_int(v_min);
    const std::int64_t j_hi = floor_to_int(v_max);
    double dv = static_cast<double>(j_lo) + 0.5 - ov;
    for (std::int64_t j = j_lo; j <= j_hi; ++j, dv += 1.0) {
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

inline PreparedBeam prepare(const Beam& beam, double resolution_m) {
  return prepare(beam, resolution_m, std::cos(beam.half_width_rad), std::sin(beam.half_width_rad));
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
  // exp(−x) as (1 − x/16)^16 (within 0.02 for x ≤ 4; the cone's edge is x = 2): no libm call per cell.
  const double x = lateral * lateral / std::max(d2, 0.25) * b.inv_two_sigma_a2;
  if (x >= 16.0) return 0.0;
  double w = 1.0 - x * (1.0 / 16.0);
  w *= w;
  w *= w;
  w *= w;
  return w * w;
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

/// Every cell of the beam with its class, skipping cells behind the return band: visit(cx, cy, d2, cls) once per
/// cell. A beam with free_on_axis_only walks its free space as a thin line (the DDA line of its axis) and its
/// wedge only for the return band; otherwise the wedge gives both.
template <typename Visit>
void for_each_beam_cell(const PreparedBeam& b, Visit&& visit) {
  if (!b.free_on_axis_only) {
    walk_cone(b, [&](std::int64_t x, std::int64_t y, double d2) {
      const CellClass cls = classify(b, x, y, d2);
      if (cls != CellClass::skip) visit(x, y, d2, cls);
    });
    return;
  }
  PreparedBeam axis = b;
  axis.half_width_rad = 0.0;
  axis.cos_half = 1.0;
  axis.sin_half = 0.0;
  walk_cone(axis, [&](std::int64_t x, std::int64_t y, double d2) {
    if (classify(b, x, y, d2) == CellClass::free) visit(x, y, d2, CellClass::free);
  });
  if (!b.has_return) return;
  // Forward distance along the major axis of the nearest hit: distance times the smallest cosine in the wedge.
  const double cos_axis = std::max(std::abs(b.ux), std::abs(b.uy));  // cos of the axis' angle to the major axis
  const double cos_min = std::max(0.0, cos_axis * b.cos_half - std::sqrt(std::max(0.0, 1.0 - cos_axis * cos_axis)) *
                                                                   b.sin_half);  // cos(angle + half width)
  walk_cone(
      b,
      [&](std::int64_t x, std::int64_t y, double d2) {
        if (classify(b, x, y, d2) == CellClass::hit) visit(x, y, d2, CellClass::hit);
      },
      b.hit_min_distance * cos_min);
}

}  // namespace wm::fusion::internal
