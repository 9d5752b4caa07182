#pragma once

// Geometry the world's sources share (plan loading, the route, the edits and the laser); not public.

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "tools/truth/world.h"

namespace wm::truth::internal {

inline constexpr double kInf = std::numeric_limits<double>::infinity();
inline constexpr double kDeg = std::numbers::pi / 180;

inline double cross(const Vec& a, const Vec& b) { return a.x() * b.y() - a.y() * b.x(); }

/// Distance along the ray to the segment; +inf when it misses.
double ray_segment(const Vec& origin, const Vec& dir, const Vec& a, const Vec& b);

/// Inside the building: at least 6 of 8 rays hit a wall within 40 m (doorways and the open sides of a pavilion let
/// some through; from outside, at most half of them meet the building).
bool inside(const std::vector<PlanWall>& walls, const Vec& p);

double route_distance(const std::vector<Polyline>& route, const Vec& a, const Vec& b);

/// Points every `step_m` along the route with their heading [m, rad].
std::vector<fusion::Pose2D> route_poses(const std::vector<Polyline>& route, double step_m);

}  // namespace wm::truth::internal
