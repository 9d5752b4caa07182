#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

// Lines in a raster's centred cell frame; not part of the public API.
namespace wm::fusion::internal {

/// A line in the centred cell frame of a width × height raster: cell (x, y) has its centre at
/// (x + 0.5 − width/2, y + 0.5 − height/2) [cells], and the line is x_c·cos θ + y_c·sin θ = rho [cells].
/// t = −x_c·sin θ + y_c·cos θ is the coordinate along it [cells].
struct CellLine {
  double cos_theta = 1.0;
  double sin_theta = 0.0;
  double rho = 0.0;

  double distance(double xc, double yc) const { return xc * cos_theta + yc * sin_theta - rho; }
  double along(double xc, double yc) const { return -xc * sin_theta + yc * cos_theta; }
  /// t of the line's point on the same row as (xc, yc) — or the same column, for a line nearer horizontal — so that
  /// every cell of one row (column) of a wall gets one t. Differs from along() by at most |distance| (the line is
  /// within 45° of that axis).
  double along_by_row(double xc, double yc) const {
    if (std::abs(sin_theta) >= std::abs(cos_theta)) return (rho * cos_theta - xc) / sin_theta;
    return (yc - rho * sin_theta) / cos_theta;
  }
};

/// Calls f(x, y, d, t) for every cell (0 <= x < width, 0 <= y < height) whose centre lies within `half_width`
/// cells of `line` (|d| <= half_width, d the signed distance) and whose coordinate t along the line is in
/// [t_lo, t_hi]. Walks the line's major axis, so the cost is O(cells visited + max(width, height)), not O(image).
/// Cells come in order of the major axis (x or y), not of t.
template <typename F>
void for_each_cell_near_line(std::int64_t width, std::int64_t height, const CellLine& line, double half_width,
                             double t_lo, double t_hi, F&& f) {
  const double half_w = 0.5 * static_cast<double>(width);
  const double half_h = 0.5 * static_cast<double>(height);
  const double c = line.cos_theta;
  const double s = line.sin_theta;
  // Along x when the line is nearer horizontal (|sin θ| >= |cos θ|: normal nearer y), else along y.
  const bool along_x = std::abs(s) >= std::abs(c);
  const std::int64_t major_size = along_x ? width : height;
  const std::int64_t minor_size = along_x ? height : width;
  const double major_half = along_x ? half_w : half_h;
  const double minor_half = along_x ? half_h : half_w;
  const double major_cos = along_x ? c : s;  // coefficient of the major coordinate in the line equation
  const double minor_cos = along_x ? s : c;  // of the minor one, |minor_cos| >= 1/√2
  std::int64_t major_lo = 0;
  std::int64_t major_hi = major_size - 1;
  if (std::isfinite(t_lo) && std::isfinite(t_hi)) {
    // Major coordinate of the line's points at t_lo and t_hi, widened by the band.
    const double dir_major = along_x ? -s : c;
    const double foot_major = line.rho * major_cos;
    const double m0 = foot_major + t_lo * dir_major;
    const double m1 = foot_major + t_hi * dir_major;
    const double lo = std::min(m0, m1) - half_width - 1.0;
    const double hi = std::max(m0, m1) + half_width + 1.0;
    major_lo = std::max<std::int64_t>(major_lo, static_cast<std::int64_t>(std::floor(lo + major_half - 0.5)));
    major_hi = std::min<std::int64_t>(major_hi, static_cast<std::int64_t>(std::ceil(hi + major_half - 0.5)));
  }
  for (std::int64_t m = major_lo; m <= major_hi; ++m) {
    const double mc = static_cast<double>(m) + 0.5 - major_half;
    // |mc·major_cos + nc·minor_cos − rho| <= half_width, solved for nc.
    const double a = (line.rho - half_width - mc * major_cos) / minor_cos;
    const double b = (line.rho + half_width - mc * major_cos) / minor_cos;
    const double nc_lo = std::min(a, b);
    const double nc_hi = std::max(a, b);
    const std::int64_t n_lo = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil(nc_lo + minor_half - 0.5)));
    const std::int64_t n_hi =
        std::min<std::int64_t>(minor_size - 1, static_cast<std::int64_t>(std::floor(nc_hi + minor_half - 0.5)));
    for (std::int64_t n = n_lo; n <= n_hi; ++n) {
      const double nc = static_cast<double>(n) + 0.5 - minor_half;
      const double xc = along_x ? mc : nc;
      const double yc = along_x ? nc : mc;
      const double d = line.distance(xc, yc);
      if (std::abs(d) > half_width) continue;
      const double t = line.along(xc, yc);
      if (t < t_lo || t > t_hi) continue;
      if (along_x) {
        f(m, n, d, t);
      } else {
        f(n, m, d, t);
      }
    }
  }
}

/// Same over the whole line.
template <typename F>
void for_each_cell_near_line(std::int64_t width, std::int64_t height, const CellLine& line, double half_width, F&& f) {
  for_each_cell_near_line(width, height, line, half_width, -std::numeric_limits<double>::infinity(),
                          std::numeric_limits<double>::infinity(), std::forward<F>(f));
}

}  // namespace wm::fusion::internal
