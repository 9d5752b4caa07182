#pragma once

// Test-only: synthetic occupancy rasters with known walls (a room with boxes; a building of rooms with doors and
// furniture), and the agreement measures the grid line tests and bench/grid_lines_bench share.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "fusion/geometry/angle.h"
#include "fusion/geometry/line.h"
#include "fusion/grid/grid_geometry.h"
#include "fusion/grid_lines/raster.h"

namespace wm::fusion::testing {

/// A true wall: centreline a → b [m] and its thickness [m].
struct TrueWall {
  Eigen::Vector2d a;
  Eigen::Vector2d b;
  double thickness_m = 0.05;

  double length_m() const { return (b - a).norm(); }
  /// The centreline as a normalized line (zero covariance).
  LineFeature line() const {
    const Eigen::Vector2d d = (b - a).normalized();
    const Eigen::Vector2d n(d.y(), -d.x());
    return LineFeature{n.dot(a), std::atan2(n.y(), n.x()), Eigen::Matrix2d::Zero()}.normalized();
  }
};

struct SyntheticMap {
  ProbabilityRaster raster;
  std::vector<TrueWall> walls;
};

/// Occupancy noise of the synthetic rasters.
struct NoiseOptions {
  float wall_p_lo = 0.70f;  // wall cells: p uniform in [lo, hi]
  float wall_p_hi = 0.98f;
  double hole_fraction = 0.02;  // wall cells that fall below the threshold (p uniform in [0.3, 0.6])
  float free_p_lo = 0.05f;      // seen free cells
  float free_p_hi = 0.40f;
  int speckles = 25;  // isolated occupied cells (half of them 2-cell clusters) in free space
};

/// Paints walls, free space and unknown space into a raster.
class RasterPainter {
 public:
  RasterPainter(GridGeometry geometry, std::uint32_t seed)
      : raster_{geometry, std::vector<float>(static_cast<std::size_t>(geometry.width() * geometry.height()),
                                             std::numeric_limits<float>::quiet_NaN())},
        rng_(seed) {}

  /// Every cell whose centre lies inside the convex polygon `corners` (counter-clockwise) becomes free (p from
  /// [lo, hi]), or unknown when `lo` is NaN.
  void fill_polygon(const std::vector<Eigen::Vector2d>& corners, float lo, float hi) {
    Eigen::Vector2d min = corners[0], max = corners[0];
    for (const auto& c : corners) {
      min = min.cwiseMin(c);
      max = max.cwiseMax(c);
    }
    for_each_cell_in(min, max, [&](std::size_t i, const Eigen::Vector2d& p) {
      for (std::size_t k = 0; k < corners.size(); ++k) {
        const Eigen::Vector2d e = corners[(k + 1) % corners.size()] - corners[k];
        const Eigen::Vector2d q = p - corners[k];
        if (e.x() * q.y() - e.y() * q.x() < 0.0) return;
      }
      raster_.p[i] = std::isnan(lo) ? lo : uniform(lo, hi);
    });
  }

  /// Draws a wall: cells whose centre is within thickness/2 of the centreline (extended by thickness/2 at both
  /// ends, so corners close) get wall occupancy, a hole_fraction of them a value below the threshold.
  void draw_wall(const TrueWall& w, const NoiseOptions& noise) {
    const double half = 0.5 * w.thickness_m;
    const Eigen::Vector2d d = (w.b - w.a).normalized();
    const Eigen::Vector2d n(-d.y(), d.x());
    const double length = w.length_m();
    const Eigen::Vector2d pad(half + 1e-9, half + 1e-9);
    for_each_cell_in(w.a.cwiseMin(w.b) - pad, w.a.cwiseMax(w.b) + pad, [&](std::size_t i, const Eigen::Vector2d& p) {
      const Eigen::Vector2d q = p - w.a;
      const double t = q.dot(d);
      // Inclusive (with rounding slack), so a 1-cell wall whose centreline runs along a cell border is drawn
      // 2 cells thick rather than not at all or on one side only.
      if (std::abs(q.dot(n)) > half + 1e-9 || t < -half - 1e-9 || t > length + half + 1e-9) return;
      raster_.p[i] = hole(noise) ? uniform(0.3f, 0.6f) : uniform(noise.wall_p_lo, noise.wall_p_hi);
    });
  }

  /// Scatters speckles over free cells at least `clearance_m` from every wall of `walls`.
  void speckle(const std::vector<TrueWall>& walls, const NoiseOptions& noise, double clearance_m) {
    const GridGeometry& g = raster_.geometry;
    std::uniform_int_distribution<std::int64_t> x(0, g.width() - 1), y(0, g.height() - 1);
    for (int placed = 0, tries = 0; placed < noise.speckles && tries < 100000; ++tries) {
      const CellIndex c{x(rng_), y(rng_)};
      const float v = raster_.p[index(c)];
      if (std::isnan(v) || v >= 0.5f) continue;
      const Eigen::Vector2d p = g.center_of(c);
      bool near = false;
      for (const auto& w : walls) near = near || distance_to_segment(p, w) < clearance_m + 0.5 * w.thickness_m;
      if (near) continue;
      raster_.p[index(c)] = uniform(0.7f, 0.95f);
      if (placed % 2 == 1 && g.contains({c.x + 1, c.y})) raster_.p[index({c.x + 1, c.y})] = uniform(0.7f, 0.95f);
      ++placed;
    }
  }

  ProbabilityRaster take() { return std::move(raster_); }
  std::mt19937& rng() { return rng_; }

  static double distance_to_segment(const Eigen::Vector2d& p, const TrueWall& w) {
    const Eigen::Vector2d ab = w.b - w.a;
    const double u = std::clamp((p - w.a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    return (w.a + u * ab - p).norm();
  }

 private:
  std::size_t index(CellIndex c) const { return static_cast<std::size_t>(c.y * raster_.geometry.width() + c.x); }

  template <typename F>
  void for_each_cell_in(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, F&& f) {
    const GridGeometry& g = raster_.geometry;
    const CellIndex c0 = g.cell_of(lo), c1 = g.cell_of(hi);
    for (std::int64_t y = std::max<std::int64_t>(0, c0.y); y <= std::min(g.height() - 1, c1.y); ++y) {
      for (std::int64_t x = std::max<std::int64_t>(0, c0.x); x <= std::min(g.width() - 1, c1.x); ++x) {
        f(index({x, y}), g.center_of({x, y}));
      }
    }
  }

  float uniform(float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(rng_); }
  bool hole(const NoiseOptions& noise) {
    return std::uniform_real_distribution<double>(0, 1)(rng_) < noise.hole_fraction;
  }

  ProbabilityRaster raster_;
  std::mt19937 rng_;
};

/// Corners of a rectangle [0, size] in a frame at `origin` turned by `angle` [rad], counter-clockwise.
inline std::vector<Eigen::Vector2d> rectangle(const Eigen::Vector2d& origin, double angle, const Eigen::Vector2d& lo,
                                              const Eigen::Vector2d& hi) {
  const Eigen::Matrix2d r =
      (Eigen::Matrix2d() << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle)).finished();
  return {origin + r * lo, origin + r * Eigen::Vector2d(hi.x(), lo.y()), origin + r * hi,
          origin + r * Eigen::Vector2d(lo.x(), hi.y())};
}

/// The four walls along a rectangle's corners.
inline std::vector<TrueWall> outline(const std::vector<Eigen::Vector2d>& corners,
                                     const std::vector<double>& thickness) {
  std::vector<TrueWall> walls;
  for (std::size_t k = 0; k < corners.size(); ++k)
    walls.push_back({corners[k], corners[(k + 1) % corners.size()], thickness[k]});
  return walls;
}

/// A room of 8 m × 6 m turned by `angle` [rad], with four boxes (one turned by another 20°), walls 1–3 cells thick
/// (chosen per wall by the seed), wall and free occupancy noise, holes and speckles, at `resolution_m`.
inline SyntheticMap room_with_boxes(std::uint32_t seed, double angle, double resolution_m = 0.05,
                                    const NoiseOptions& noise = {}) {
  std::mt19937 pick(seed * 7919u + 17u);
  auto thickness = [&] { return resolution_m * std::uniform_int_distribution<int>(1, 3)(pick); };
  const Eigen::Vector2d origin(1.13 + 0.01 * (seed % 7), 0.77 + 0.013 * (seed % 5));
  const auto room = rectangle(origin, angle, {0, 0}, {8, 6});
  Eigen::Vector2d lo = room[0], hi = room[0];
  for (const auto& c : room) {
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
  }
  const double margin = 0.4;
  const GridGeometry geometry(lo - Eigen::Vector2d(margin, margin), resolution_m,
                              static_cast<std::int64_t>(std::ceil((hi.x() - lo.x() + 2 * margin) / resolution_m)),
                              static_cast<std::int64_t>(std::ceil((hi.y() - lo.y() + 2 * margin) / resolution_m)));
  RasterPainter painter(geometry, seed);
  painter.fill_polygon(room, noise.free_p_lo, noise.free_p_hi);
  std::vector<TrueWall> walls = outline(room, {thickness(), thickness(), thickness(), thickness()});
  struct Box {
    Eigen::Vector2d lo, hi;
    double turn;
  };
  const std::vector<Box> boxes = {{{1.0, 1.0}, {2.2, 1.8}, 0.0},
                                  {{5.0, 1.2}, {6.6, 2.0}, 0.0},
                                  {{1.2, 3.8}, {2.0, 4.9}, 0.0},
                                  {{4.6, 3.6}, {5.8, 4.6}, 20.0 * std::numbers::pi / 180}};
  for (const Box& b : boxes) {
    const Eigen::Vector2d mid = 0.5 * (b.lo + b.hi);
    const Eigen::Matrix2d r =
        (Eigen::Matrix2d() << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle)).finished();
    const auto corners = rectangle(origin + r * mid, angle + b.turn, b.lo - mid, b.hi - mid);
    painter.fill_polygon(corners, std::numeric_limits<float>::quiet_NaN(), 0.0f);  // inside a box: never seen
    for (const TrueWall& w : outline(corners, {thickness(), thickness(), thickness(), thickness()})) walls.push_back(w);
  }
  for (const TrueWall& w : walls) painter.draw_wall(w, noise);
  painter.speckle(walls, noise, 0.25);
  return {painter.take(), walls};
}

/// A building of rooms_x × rooms_y rooms of room_m × room_m, walls 3 cells thick with a door (0.9 m gap) in
/// every inner wall, and two pieces of furniture per room (boxes 0.5–1 m, one turned; room_m >= 4.5), outlines 1–2
/// cells thick, at `resolution_m`. Collinear walls are separate true walls (split at the doors).
inline SyntheticMap building(std::uint32_t seed, int rooms_x, int rooms_y, double room_m, double resolution_m = 0.05,
                             const NoiseOptions& noise = {}) {
  std::mt19937 pick(seed);
  const double margin = 0.5;
  const Eigen::Vector2d origin(margin, margin);
  const double size_x = rooms_x * room_m, size_y = rooms_y * room_m;
  const GridGeometry geometry(Eigen::Vector2d::Zero(), resolution_m,
                              static_cast<std::int64_t>(std::ceil((size_x + 2 * margin) / resolution_m)),
                              static_cast<std::int64_t>(std::ceil((size_y + 2 * margin) / resolution_m)));
  RasterPainter painter(geometry, seed);
  painter.fill_polygon(rectangle(origin, 0.0, {0, 0}, {size_x, size_y}), noise.free_p_lo, noise.free_p_hi);
  std::vector<TrueWall> walls;
  const double wall = 3 * resolution_m;
  const double door = 0.9;
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  // A wall from a to b with a door in the middle of [a, b] unless `outer`.
  auto add_wall = [&](Eigen::Vector2d a, Eigen::Vector2d b, bool outer) {
    if (outer) {
      walls.push_back({a, b, wall});
      return;
    }
    const Eigen::Vector2d d = (b - a).normalized();
    const double at = (0.3 + 0.4 * unit(pick)) * (b - a).norm();
    walls.push_back({a, a + (at - 0.5 * door) * d, wall});
    walls.push_back({a + (at + 0.5 * door) * d, b, wall});
  };
  for (int i = 0; i <= rooms_x; ++i) {
    for (int j = 0; j < rooms_y; ++j) {
      add_wall(origin + Eigen::Vector2d(i * room_m, j * room_m), origin + Eigen::Vector2d(i * room_m, (j + 1) * room_m),
               i == 0 || i == rooms_x);
    }
  }
  for (int j = 0; j <= rooms_y; ++j) {
    for (int i = 0; i < rooms_x; ++i) {
      add_wall(origin + Eigen::Vector2d(i * room_m, j * room_m), origin + Eigen::Vector2d((i + 1) * room_m, j * room_m),
               j == 0 || j == rooms_y);
    }
  }
  for (int i = 0; i < rooms_x; ++i) {
    for (int j = 0; j < rooms_y; ++j) {
      for (int k = 0; k < 2; ++k) {
        const Eigen::Vector2d size(0.5 + 0.5 * unit(pick), 0.5 + 0.5 * unit(pick));
        const double turn = k == 1 ? (10.0 + 60.0 * unit(pick)) * std::numbers::pi / 180 : 0.0;
        // One piece in each half of the room, centres at least 0.2·room_m + 0.7 m from the room's walls (their
        // turned half-diagonal is at most 0.71 m), so furniture never touches a wall or the other piece.
        const Eigen::Vector2d centre =
            origin + room_m * Eigen::Vector2d(i + (k == 0 ? 0.25 : 0.75) + 0.05 * (2 * unit(pick) - 1),
                                              j + 0.3 + 0.4 * unit(pick));
        const auto corners = rectangle(centre, turn, -0.5 * size, 0.5 * size);
        painter.fill_polygon(corners, std::numeric_limits<float>::quiet_NaN(), 0.0f);
        const double t = resolution_m * (1 + static_cast<int>(unit(pick) * 2));
        for (const TrueWall& w : outline(corners, {t, t, t, t})) walls.push_back(w);
      }
    }
  }
  for (const TrueWall& w : walls) painter.draw_wall(w, noise);
  painter.speckle(walls, noise, 0.25);
  return {painter.take(), walls};
}

/// |Δρ| [m] and |Δφ| [rad] between two lines, comparing like with like ((ρ, φ) and (−ρ, φ + π) are one line).
struct LineDifference {
  double rho_m;
  double phi_rad;
};
inline LineDifference difference(const LineFeature& a, const LineFeature& b) {
  double dphi = normalize_angle(a.phi_rad - b.phi_rad);
  double rho_b = b.rho_m;
  if (std::abs(dphi) > std::numbers::pi / 2) {
    dphi = normalize_angle(dphi - std::numbers::pi);
    rho_b = -rho_b;
  }
  return {std::abs(a.rho_m - rho_b), std::abs(dphi)};
}

/// Length of the overlap [m] of the segment p0–p1 projected on the wall's centreline with the wall itself.
inline double overlap_m(const TrueWall& w, const Eigen::Vector2d& p0, const Eigen::Vector2d& p1) {
  const Eigen::Vector2d d = (w.b - w.a).normalized();
  const double s0 = (p0 - w.a).dot(d), s1 = (p1 - w.a).dot(d);
  return std::max(0.0, std::min(w.length_m(), std::max(s0, s1)) - std::max(0.0, std::min(s0, s1)));
}

/// Tolerances of "found": line within (rho_m, phi_rad) and, for segments, overlapping at least `overlap`
/// of the wall's length.
struct Tolerance {
  double rho_m = 0.02;
  double phi_rad = 0.5 * std::numbers::pi / 180;
  double overlap = 0.5;
};

/// True when segment s lies on wall w within the tolerance.
inline bool segment_matches(const TrueWall& w, const LineSegment& s, const Tolerance& tol) {
  const LineDifference diff = difference(w.line(), s.line);
  return diff.rho_m < tol.rho_m && diff.phi_rad < tol.phi_rad &&
         overlap_m(w, s.p0(), s.p1()) >= tol.overlap * w.length_m();
}

/// True when the infinite line l is the wall's line within the tolerance.
inline bool line_matches(const TrueWall& w, const LineFeature& l, const Tolerance& tol) {
  const LineDifference diff = difference(w.line(), l);
  return diff.rho_m < tol.rho_m && diff.phi_rad < tol.phi_rad;
}

/// Distance [m] from the wall's midpoint to a line: Δρ measured where the wall is. The Hesse ρ about the map origin
/// would multiply every angle error by the wall's distance from that origin (5 m away, 0.5° alone is 4.4 cm).
inline double offset_at_wall(const TrueWall& w, const LineFeature& l) {
  const Eigen::Vector2d mid = 0.5 * (w.a + w.b);
  return std::abs(mid.x() * std::cos(l.phi_rad) + mid.y() * std::sin(l.phi_rad) - l.rho_m);
}

/// What the raster can tell about a wall: the 2 cm and 0.5°, widened to the digitisation limit where that is
/// coarser — a wall drawn one cell thick is only known to half a cell across, and the staircase of a straight run of
/// L/Δ cells to about half a cell over its length. At 2.5 cm cells this is the bound for every wall of 1.43 m
/// or longer (0.9° at the boxes' 0.8 m sides); at 5 cm it is 3 cm and, for a 0.8 m side, 1.8°.
struct WallTolerance {
  double offset_m;
  double phi_rad;
};
inline WallTolerance digitisation_tolerance(const TrueWall& w, double resolution_m) {
  return {std::max(0.02, 0.5 * resolution_m + 0.005),
          std::max(0.5 * std::numbers::pi / 180, std::atan2(0.5 * resolution_m, w.length_m()))};
}

/// True when segment s finds wall w: its line within the tolerance about the wall's midpoint, covering at least half
/// of the wall.
inline bool found_within(const TrueWall& w, const LineSegment& s, const WallTolerance& tol) {
  return offset_at_wall(w, s.line) < tol.offset_m && difference(w.line(), s.line).phi_rad < tol.phi_rad &&
         overlap_m(w, s.p0(), s.p1()) >= 0.5 * w.length_m();
}

/// How many of `walls` some segment finds within the digitisation tolerance; the others are added to `missed`.
inline std::size_t count_found(const std::vector<TrueWall>& walls, const std::vector<LineSegment>& segments,
                               double resolution_m, std::vector<const TrueWall*>* missed = nullptr) {
  std::size_t found = 0;
  for (const TrueWall& w : walls) {
    bool hit = false;
    for (const LineSegment& s : segments) hit = hit || found_within(w, s, digitisation_tolerance(w, resolution_m));
    if (hit)
      ++found;
    else if (missed != nullptr)
      missed->push_back(&w);
  }
  return found;
}

inline std::vector<TrueWall> longer_than(const std::vector<TrueWall>& walls, double length_m) {
  std::vector<TrueWall> out;
  for (const TrueWall& w : walls) {
    if (w.length_m() > length_m) out.push_back(w);
  }
  return out;
}

/// True when line l is the wall's line, loosely (3°, 5 cm at the wall): for coverage and spurious segments.
inline bool on_wall_line(const TrueWall& w, const LineFeature& l) {
  return difference(w.line(), l).phi_rad < 3 * std::numbers::pi / 180 && offset_at_wall(w, l) < 0.05;
}

/// The segments longer than 0.3 m that are spurious: not on a true wall's line, or reaching beyond the walls along
/// that line (collinear true walls that meet, like an outer wall split where inner walls join it, count as one). A
/// segment's end may pass the centreline's end by half the thickness of the wall met there plus half a cell.
inline std::vector<const LineSegment*> spurious_segments(const SyntheticMap& map,
                                                         const std::vector<LineSegment>& segments) {
  double thickest = 0.0;
  for (const TrueWall& w : map.walls) thickest = std::max(thickest, w.thickness_m);
  const double slack = thickest + map.raster.geometry.resolution_m() + 0.02;
  std::vector<const LineSegment*> spurious;
  for (const LineSegment& s : segments) {
    if (s.length_m() <= 0.3) continue;
    double on_walls = 0.0;
    for (const TrueWall& w : map.walls) {
      if (on_wall_line(w, s.line)) on_walls += overlap_m(w, s.p0(), s.p1());
    }
    if (on_walls < s.length_m() - slack) spurious.push_back(&s);
  }
  return spurious;
}

}  // namespace wm::fusion::testing
