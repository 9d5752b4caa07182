#include "fusion/grid_lines/internal/raster_frame.h"

#include <cmath>

namespace wm::fusion::internal {

Eigen::Vector2d raster_center_m(const GridGeometry& geometry) {
  return geometry.origin_m() +
         0.5 * geometry.resolution_m() *
             Eigen::Vector2d(static_cast<double>(geometry.width()), static_cast<double>(geometry.height()));
}

Eigen::Vector2d world_point(const GridGeometry& geometry, double xc, double yc) {
  return raster_center_m(geometry) + geometry.resolution_m() * Eigen::Vector2d(xc, yc);
}

LineFeature world_line(const CellLine& line, const GridGeometry& geometry) {
  // n·(X − c0) = res·ρ_c  ⇒  n·X = res·ρ_c + n·c0.
  const Eigen::Vector2d n(line.cos_theta, line.sin_theta);
  LineFeature world;
  world.rho_m = geometry.resolution_m() * line.rho + n.dot(raster_center_m(geometry));
  world.phi_rad = std::atan2(line.sin_theta, line.cos_theta);
  return world.normalized();
}

CellLine cell_line(const LineFeature& line, const GridGeometry& geometry) {
  const Eigen::Vector2d n = line.normal();
  return {n.x(), n.y(), (line.rho_m - n.dot(raster_center_m(geometry))) / geometry.resolution_m()};
}

}  // namespace wm::fusion::internal
