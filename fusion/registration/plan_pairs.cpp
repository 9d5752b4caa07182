#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <string>

#include "fusion/registration/plan_registration.h"
#include "fusion/registration/plan_registration_internal.h"

namespace wm::fusion {
using namespace internal;

PairsPlacement place_from_pairs(const std::vector<PointPair>& pairs, bool with_scale, double point_sigma_m) {
  if (pairs.size() < 2) throw RegistrationError("pairs: at least two point pairs are needed");
  // Dynamic sizes: Umeyama on Matrix2Xd trips a GCC 12 stringop-overread warning inside Eigen.
  Eigen::MatrixXd drawn(2, pairs.size()), world(2, pairs.size());
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (!finite(pairs[i].drawn) || !finite(pairs[i].world))
      throw RegistrationError("pairs[" + std::to_string(i) + "]: expected finite coordinates");
    drawn.col(static_cast<Eigen::Index>(i)) = pairs[i].drawn;
    world.col(static_cast<Eigen::Index>(i)) = pairs[i].world;
  }
  const auto spread = [](const Eigen::MatrixXd& m) { return (m.colwise() - m.rowwise().mean()).norm(); };
  // Points closer than a millimetre (drawn: relative to the drawing's own extent) leave the rotation undetermined.
  if (spread(drawn) <= 1e-9 * std::max(1.0, drawn.cwiseAbs().maxCoeff()) || spread(world) < 1e-3)
    throw RegistrationError("pairs: the points coincide, so the rotation is undetermined");
  const Eigen::MatrixXd t = Eigen::umeyama(drawn, world, with_scale);
  PairsPlacement result;
  const double scale = t.block<2, 2>(0, 0).col(0).norm();
  result.placement = {t(0, 2), t(1, 2), std::atan2(t(1, 0), t(0, 0)), with_scale ? scale : 1.0};
  // Covariance by the same small similarity about the world points' centroid as the refinement uses.
  const Eigen::Vector2d centroid = world.rowwise().mean();
  Eigen::Matrix4d normal_matrix = Eigen::Matrix4d::Zero();
  double sq = 0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Eigen::Vector2d placed = result.placement.transform_point(pairs[i].drawn);
    sq += (pairs[i].world - placed).squaredNorm();
    for (int axis = 0; axis < 2; ++axis) {
      Eigen::Vector4d j;
      j.head<2>() = Eigen::Vector2d::Unit(axis);
      j(2) = perp(placed - centroid)(axis);
      j(3) = with_scale ? (placed - centroid)(axis) : 0.0;
      normal_matrix += j * j.transpose();
    }
  }
  if (!with_scale) normal_matrix(3, 3) = 1;
  const auto unknowns = with_scale ? 4.0 : 3.0;
  const double dof = 2.0 * static_cast<double>(pairs.size()) - unknowns;
  result.rms_m = std::sqrt(sq / static_cast<double>(pairs.size()));
  const double sigma_sq = std::max(point_sigma_m * point_sigma_m, dof > 0 ? sq / dof : 0.0);
  result.covariance = placement_cov(result.placement, centroid, sigma_sq * normal_matrix.inverse(), with_scale);
  return result;
}

}  // namespace wm::fusion
