#pragma once

// Helpers shared by the plan registration's sources (search, directions, refinement, scoring, pairs); not public.

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <optional>
#include <vector>

#include "fusion/registration/plan_registration.h"

namespace wm::fusion::internal {

inline constexpr double kPi = 3.14159265358979323846;

inline bool finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

inline Eigen::Vector2d perp(const Eigen::Vector2d& v) { return {-v.y(), v.x()}; }

inline double total_length(const std::vector<DrawnEdge>& edges) {
  double length = 0;
  for (const auto& e : edges) length += (e.p1 - e.p0).norm();
  return length;
}

// `count` points spread evenly by length along the edges (each in the middle of its stretch), drawn frame.
std::vector<Eigen::Vector2d> sample_edges(const std::vector<DrawnEdge>& edges, std::size_t count);

// Shifts of the rotation between the drawing and the occupied cells from their direction histograms; nullopt when
// there is no clear peak.
std::optional<std::vector<double>> direction_peaks(const std::vector<DrawnEdge>& edges, const ObservedMap& observed,
                                                   double occupied_probability);

// Occupied cells and element points, the data the refinement fits the drawn edges to.
std::vector<Eigen::Vector2d> observed_points(const ObservedMap& observed, double occupied_probability);

// The covariance of a placement from that of the small similarity about `pivot` it was solved for, (dt, dθ, ds) with
// t' = m + (1 + ds)·R(dθ)·(t − m) + dt, θ' = θ + dθ, s' = s·(1 + ds). The scale's row and column are zero when held.
Eigen::Matrix4d placement_cov(const Similarity2D& placement, const Eigen::Vector2d& pivot, Eigen::Matrix4d correction,
                              bool with_scale);

struct Refined {
  Similarity2D placement;
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  double rms_m = 0;
  std::size_t matched = 0;
};

// Gauss-Newton on point-to-line distances of the observed points to the nearest placed edge within a band that
// narrows from `band0` to two cells. The unknowns are a small similarity about the matched points' centroid m,
// x ↦ m + (1 + ds)·R(dθ)·(x − m) + dt, so the lever arms stay the building's size whatever the drawing's origin.
Refined refine(const std::vector<DrawnEdge>& edges, const std::vector<Eigen::Vector2d>& points, Similarity2D placement,
               double band0, double cell_m, bool with_scale);

}  // namespace wm::fusion::internal
