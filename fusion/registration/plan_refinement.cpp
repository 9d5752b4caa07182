#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

#include "fusion/registration/plan_registration_internal.h"

namespace wm::fusion::internal {

std::vector<Eigen::Vector2d> observed_points(const ObservedMap& observed, double occupied_probability) {
  std::vector<Eigen::Vector2d> points = observed.element_points;
  const auto& g = observed.geometry;
  for (std::int64_t y = 0; y < g.height(); ++y)
    for (std::int64_t x = 0; x < g.width(); ++x)
      if (observed.probability[static_cast<std::size_t>(y * g.width() + x)] > occupied_probability)
        points.push_back(g.center_of({x, y}));
  return points;
}

// The covariance of a placement from that of the small similarity about `pivot` it was solved for, (dt, dθ, ds) with
// t' = m + (1 + ds)·R(dθ)·(t − m) + dt, θ' = θ + dθ, s' = s·(1 + ds). The scale's row and column are zero when held.
Eigen::Matrix4d placement_cov(const Similarity2D& placement, const Eigen::Vector2d& pivot, Eigen::Matrix4d correction,
                              bool with_scale) {
  if (!with_scale) {
    correction.row(3).setZero();
    correction.col(3).setZero();
  }
  const Eigen::Vector2d lever = Eigen::Vector2d(placement.x_m, placement.y_m) - pivot;
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  a.block<2, 2>(0, 0).setIdentity();
  a.block<2, 1>(0, 2) = perp(lever);
  a.block<2, 1>(0, 3) = lever;
  a(2, 2) = 1;
  a(3, 3) = placement.scale;
  return a * correction * a.transpose();
}

Refined refine(const std::vector<DrawnEdge>& edges, const std::vector<Eigen::Vector2d>& points, Similarity2D placement,
               double band0, double cell_m, bool with_scale) {
  Refined result;
  const int unknowns = with_scale ? 4 : 3;
  const double band_min = 2.0 * cell_m;
  double band = std::max(band0, band_min);
  struct Placed {
    Eigen::Vector2d a, dir, normal;
    double length;
  };
  std::vector<Placed> placed(edges.size());
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& q : points) {
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  for (int iteration = 0; iteration < 40; ++iteration) {
    for (std::size_t i = 0; i < edges.size(); ++i) {
      const Eigen::Vector2d a = placement.transform_point(edges[i].p0), b = placement.transform_point(edges[i].p1);
      const double length = (b - a).norm();
      const Eigen::Vector2d dir = length > 0 ? Eigen::Vector2d((b - a) / length) : Eigen::Vector2d(1, 0);
      placed[i] = {a, dir, perp(dir), length};
    }
    // Edges by bucket of `bucket` m, each in every bucket its band-widened box touches.
    const double bucket = std::max(1.0, 2 * band);
    const std::int64_t points_box[4] = {static_cast<std::int64_t>(std::floor(lo.x() / bucket)) - 1,
                                        static_cast<std::int64_t>(std::floor(lo.y() / bucket)) - 1,
                                        static_cast<std::int64_t>(std::floor(hi.x() / bucket)) + 1,
                                        static_cast<std::int64_t>(std::floor(hi.y() / bucket)) + 1};
    std::unordered_map<std::int64_t, std::vector<std::uint32_t>> buckets;
    std::size_t entries = 0;  // bounded: an absurd plan must not exhaust memory here
    const auto key = [](std::int64_t bx, std::int64_t by) { return bx * 73856093LL ^ by * 19349663LL; };
    for (std::size_t i = 0; i < placed.size(); ++i) {
      const auto& e = placed[i];
      const Eigen::Vector2d b = e.a + e.dir * e.length;
      const auto x0 = static_cast<std::int64_t>(std::floor((std::min(e.a.x(), b.x()) - band) / bucket));
      const auto x1 = static_cast<std::int64_t>(std::floor((std::max(e.a.x(), b.x()) + band) / bucket));
      const auto y0 = static_cast<std::int64_t>(std::floor((std::min(e.a.y(), b.y()) - band) / bucket));
      const auto y1 = static_cast<std::int64_t>(std::floor((std::max(e.a.y(), b.y()) + band) / bucket));
      // Only where there are observed points: an edge's box is clipped to theirs.
      const auto cx0 = std::max(x0, points_box[0]), cx1 = std::min(x1, points_box[2]);
      const auto cy0 = std::max(y0, points_box[1]), cy1 = std::min(y1, points_box[3]);
      if (cx0 > cx1 || cy0 > cy1) continue;
      const auto cells = static_cast<std::size_t>((cx1 - cx0 + 1) * (cy1 - cy0 + 1));
      if (cells > 1'000'000 || entries + cells > 20'000'000) continue;  // absurd edges are left to the search
      entries += cells;
      for (auto by = cy0; by <= cy1; ++by)
        for (auto bx = cx0; bx <= cx1; ++bx) buckets[key(bx, by)].push_back(static_cast<std::uint32_t>(i));
    }
    struct Match {
      Eigen::Vector2d q, normal;
      double offset;  // n·x = offset on the placed edge's line
    };
    std::vector<Match> matches;
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (const auto& q : points) {
      const auto it = buckets.find(key(static_cast<std::int64_t>(std::floor(q.x() / bucket)),
                                       static_cast<std::int64_t>(std::floor(q.y() / bucket))));
      if (it == buckets.end()) continue;
      double nearest = band;
      const Placed* match = nullptr;
      for (const auto i : it->second) {
        const auto& e = placed[i];
        const double u = e.dir.dot(q - e.a);
        if (u < -cell_m || u > e.length + cell_m) continue;
        const double d = std::abs(e.normal.dot(q - e.a));
        if (d < nearest) {
          nearest = d;
          match = &e;
        }
      }
      if (!match) continue;
      matches.push_back({q, match->normal, match->normal.dot(match->a)});
      centroid += q;
    }
    if (matches.size() < static_cast<std::size_t>(unknowns) + 1) break;
    centroid /= static_cast<double>(matches.size());
    Eigen::Matrix4d normal_matrix = Eigen::Matrix4d::Zero();
    Eigen::Vector4d gradient = Eigen::Vector4d::Zero();
    double weighted_sq = 0, weight_sum = 0;
    for (const auto& m : matches) {
      const double r = m.normal.dot(m.q) - m.offset;
      const double w = std::abs(r) <= cell_m ? 1.0 : cell_m / std::abs(r);  // Huber
      Eigen::Vector4d j(-m.normal.x(), -m.normal.y(), perp(m.normal).dot(m.q - centroid),
                        -(m.offset - m.normal.dot(centroid)));
      if (!with_scale) j(3) = 0;
      normal_matrix += w * j * j.transpose();
      gradient += w * j * r;
      weighted_sq += w * r * r;
      weight_sum += w;
    }
    if (!with_scale) normal_matrix(3, 3) = 1;
    const Eigen::Matrix4d inverse = normal_matrix.inverse();
    if (!inverse.allFinite()) break;
    const Eigen::Vector4d delta = -inverse * gradient;
    // Compose the correction after the placement.
    const Eigen::Vector2d t(placement.x_m, placement.y_m);
    const Eigen::Vector2d t_new =
        centroid + (1 + delta(3)) * (Eigen::Rotation2Dd(delta(2)) * (t - centroid)) + delta.head<2>();
    placement = {t_new.x(), t_new.y(), placement.theta_rad + delta(2), placement.scale * (1 + delta(3))};
    result.placement = placement;
    result.matched = matches.size();
    const double dof = std::max(1.0, static_cast<double>(matches.size()) - unknowns);
    const double sigma_sq = weighted_sq / dof;
    result.rms_m = std::sqrt(weighted_sq / std::max(weight_sum, 1.0));
    result.covariance = placement_cov(placement, centroid, sigma_sq * inverse, with_scale);
    const bool settled = delta.head<2>().norm() < 1e-4 && std::abs(delta(2)) < 1e-6 && std::abs(delta(3)) < 1e-7;
    if (settled && band <= band_min) break;
    band = std::max(band_min, band * 0.7);
  }
  if (result.matched == 0) result.placement = placement;
  return result;
}

}  // namespace wm::fusion::internal
