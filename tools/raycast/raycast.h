#pragma once

// Laser scans simulated inside a floor plan: every beam ray-cast against every line, with range noise. For tests
// with a known answer (plan registration) and for wm-raycast-log, which writes them as a CARMEN log.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "fusion/grid/scan.h"

namespace wm::raycast {

struct PlanLine {
  Eigen::Vector2d p0, p1;
};

/// The lines of an AMRL vector map file (a JSON array of {"p0": {"x", "y"}, "p1": {"x", "y"}}, metres).
/// @throw std::runtime_error for a file that cannot be read or holds no line.
std::vector<PlanLine> read_vectormap(const std::string& path);

/// Distance along the ray to the nearest line; +inf when none is hit within max_range.
double cast_ray(const std::vector<PlanLine>& lines, const Eigen::Vector2d& origin, const Eigen::Vector2d& dir,
                double max_range);

/// GDC1's robot route (the nodes of its navigation graph, ut-amrl/amrl_maps GDC1/GDC1.navigation.json: 1-0-2-4-5-3
/// and the spurs 4-7, 4-8, 5-6), as polylines [m].
std::vector<std::vector<Eigen::Vector2d>> gdc1_route();

struct DriveOptions {
  double step_m = 0.5;      // between scans along the route
  int beams = 720;          // over 360°
  double max_range_m = 20;  // no return beyond
  double sigma_range_m = 0.01;
  unsigned seed = 7;
};

/// Scans every step along the route, heading along it.
std::vector<fusion::LaserScan> simulate_scans(const std::vector<PlanLine>& lines,
                                              const std::vector<std::vector<Eigen::Vector2d>>& route,
                                              const DriveOptions& options = {});

}  // namespace wm::raycast
