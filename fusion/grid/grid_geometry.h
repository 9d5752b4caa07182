#pragma once

#include <Eigen/Core>
#include <cmath>
#include <compare>
#include <cstdint>

namespace wm::fusion {

/// Integer index of a grid cell: x grows with world x (columns), y with world y (rows). May be negative.
struct CellIndex {
  std::int64_t x = 0;
  std::int64_t y = 0;
  bool operator==(const CellIndex&) const = default;
};

/// Index of a square tile of T × T cells: tile (x, y) holds cells [x·T, (x+1)·T) × [y·T, (y+1)·T).
struct TileIndex {
  std::int64_t x = 0;
  std::int64_t y = 0;
  auto operator<=>(const TileIndex&) const = default;
};

/// A cell as its tile and its place in the tile.
struct TileCell {
  TileIndex tile;
  std::int64_t x = 0;  // [0, T)
  std::int64_t y = 0;  // [0, T)
};

/// The tile of `tile_size` cells a side holding cell c, by floor division (cell −1 lies in tile −1, at T − 1).
/// tile_size > 0.
inline TileCell tile_of(CellIndex c, std::int64_t tile_size) {
  const auto floor_div = [](std::int64_t a, std::int64_t b) { return a / b - (a % b != 0 && (a < 0) != (b < 0)); };
  const TileIndex t{floor_div(c.x, tile_size), floor_div(c.y, tile_size)};
  return {t, c.x - t.x * tile_size, c.y - t.y * tile_size};
}

/// Max pooling into a coarse cell: the largest known value pooled into it wins; NaN (unknown) never does.
inline void pool_max(float& cell, float value) {
  if (!std::isnan(value) && (std::isnan(cell) || value > cell)) cell = value;
}

/// The extent of a finite raster, modelled on Cartographer's MapLimits but in the ROS map_server convention (so
/// exported grids load there unchanged): origin = world position [m] of the lower-left corner of cell (0, 0),
/// cells of `resolution` m, `width` columns along world x and `height` rows along world y, stored row-major from
/// the bottom row.
/// Invariant: origin finite, 0 < resolution <= 100 m, 1 <= width, height <= 1'000'000.
class GridGeometry {
 public:
  static constexpr double kMaxResolutionM = 100.0;
  static constexpr std::int64_t kMaxSizeCells = 1'000'000;

  /// @throw std::invalid_argument for a non-finite origin, resolution <= 0 or > 100 m (or NaN),
  ///        width/height <= 0 or > 1'000'000.
  GridGeometry(Eigen::Vector2d origin_m, double resolution_m, std::int64_t width, std::int64_t height);

  const Eigen::Vector2d& origin_m() const { return origin_m_; }
  double resolution_m() const { return resolution_m_; }
  std::int64_t width() const { return width_; }
  std::int64_t height() const { return height_; }

  /// The cell containing world point p [m] (floor, so a point on a cell border belongs to the cell above /
  /// right of it), also outside the bounds (indices may be negative or >= width/height).
  /// @throw std::out_of_range for a non-finite p or one whose index does not fit in ±2^52 cells.
  CellIndex cell_of(const Eigen::Vector2d& p) const;
  /// World position [m] of the centre of cell c (c need not be inside the bounds).
  Eigen::Vector2d center_of(CellIndex c) const;
  /// True when 0 <= c.x < width and 0 <= c.y < height.
  bool contains(CellIndex c) const;

 private:
  Eigen::Vector2d origin_m_;
  double resolution_m_;
  std::int64_t width_;
  std::int64_t height_;
};

/// Cells [first, end) of the lattice with cell (0, 0)'s lower-left corner at the world origin.
struct CellRange {
  CellIndex first;
  CellIndex end;
  std::int64_t width() const { return end.x - first.x; }
  std::int64_t height() const { return end.y - first.y; }
  /// As a raster of `resolution_m` cells. @throw std::invalid_argument when empty or beyond GridGeometry's limits.
  GridGeometry geometry(double resolution_m) const;
};

/// The cell of that lattice (cells of `resolution_m`) holding p, as GridGeometry::cell_of with the origin at (0, 0).
/// @throw std::out_of_range for a non-finite p or one whose index does not fit in ±2^52 cells;
///        std::invalid_argument for a resolution that is not > 0.
CellIndex cell_at(const Eigen::Vector2d& p, double resolution_m);

/// The cells of that lattice covering the box [lo, hi] [m], snapped outwards (a corner on a cell border takes no cell
/// beyond it). @throw as cell_at, and std::invalid_argument when lo is not <= hi.
CellRange covering(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, double resolution_m);

}  // namespace wm::fusion
