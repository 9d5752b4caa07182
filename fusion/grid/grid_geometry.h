#pragma once

#include <Eigen/Core>
#include <cstdint>

namespace wm::fusion {

/// Integer index of a grid cell: x grows with world x (columns), y with world y (rows). May be negative.
struct CellIndex {
  std::int64_t x = 0;
  std::int64_t y = 0;
  bool operator==(const CellIndex&) const = default;
};

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

}  // namespace wm::fusion
