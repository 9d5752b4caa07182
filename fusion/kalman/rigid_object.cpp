#include "fusion/kalman/rigid_object.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "fusion/geometry/angle.h"
#include "fusion/internal/line_algebra.h"

namespace wm::fusion {
namespace {

constexpr double kMinEdgeLength = 1e-9;  // [m]

bool finite(const Pose2D& pose) {
  return std::isfinite(pose.x_m) && std::isfinite(pose.y_m) && std::isfinite(pose.theta_rad);
}

// (ρ_kᵒ, φ_kᵒ) of the edge's line in the object frame; which of the two representations is irrelevant because
// every consumer either normalizes or re-aligns against it.
LineFeature local_line(const LocalEdge& edge) {
  const Eigen::Vector2d d = (edge.p1 - edge.p0).normalized();
  const Eigen::Vector2d n(d.y(), -d.x());
  return LineFeature{n.dot(edge.p0), std::atan2(n.y(), n.x()), Eigen::Matrix2d::Zero()};
}

void check_index(std::size_t k, std::size_t size, const char* caller) {
  if (k >= size)
    throw std::out_of_range(std::string(caller) + ": edge " + std::to_string(k) + " out of range (object has " +
                            std::to_string(size) + " edges)");
}

}  // namespace

RigidObject::RigidObject(Pose2D pose, Eigen::Matrix3d pose_cov, std::vector<LocalEdge> edges)
    : pose_(pose), pose_cov_(std::move(pose_cov)), edges_(std::move(edges)) {
  constexpr const char* kCaller = "RigidObject::RigidObject";
  if (edges_.empty()) throw std::invalid_argument(std::string(kCaller) + ": no edges");
  for (std::size_t i = 0; i < edges_.size(); ++i) {
    const LocalEdge& e = edges_[i];
    if (!e.p0.allFinite() || !e.p1.allFinite())
      throw std::invalid_argument(std::string(kCaller) + ": edge " + std::to_string(i) + " is not finite");
    if (!((e.p1 - e.p0).norm() >= kMinEdgeLength))
      throw std::invalid_argument(std::string(kCaller) + ": edge " + std::to_string(i) + " is shorter than 1e-9 m");
  }
  if (!finite(pose_)) throw std::invalid_argument(std::string(kCaller) + ": pose is not finite");
  internal::require_finite(pose_cov_, kCaller, "pose_cov");
  const double scale = pose_cov_.cwiseAbs().maxCoeff();
  if (((pose_cov_ - pose_cov_.transpose()).cwiseAbs().array() > 1e-9 * scale).any())
    throw std::invalid_argument(std::string(kCaller) + ": pose_cov is not symmetric");
  pose_cov_ = (0.5 * (pose_cov_ + pose_cov_.transpose())).eval();  // eval: the transpose aliases
  // PSD, not PD: an exactly known pose (zero covariance) is legitimate. The tolerance absorbs round-off of
  // covariances that went through the Joseph update or storage.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(pose_cov_, Eigen::EigenvaluesOnly);
  if (eig.eigenvalues().minCoeff() < -1e-12 * scale)
    throw std::invalid_argument(std::string(kCaller) + ": pose_cov is not positive semi-definite");
}

LineSegment RigidObject::world_edge(std::size_t k, const Eigen::Matrix2d& edge_noise) const {
  constexpr const char* kCaller = "RigidObject::world_edge";
  check_index(k, edges_.size(), kCaller);
  internal::require_finite(edge_noise, kCaller, "edge_noise");
  const LineFeature local = local_line(edges_[k]);
  const internal::TransformedLine h = internal::transform_line_raw(local.rho_m, local.phi_rad, pose_);
  LineSegment segment;
  segment.line = LineFeature{h.rho_m, h.phi_rad, h.d_pose * pose_cov_ * h.d_pose.transpose()}.normalized();
  segment.line.cov += 0.5 * (edge_noise + edge_noise.transpose());
  const double ta = segment.line.coordinate_along(pose_.transform_point(edges_[k].p0));
  const double tb = segment.line.coordinate_along(pose_.transform_point(edges_[k].p1));
  segment.t0_m = std::min(ta, tb);
  segment.t1_m = std::max(ta, tb);
  return segment;
}

std::vector<LineSegment> RigidObject::world_edges(const Eigen::Matrix2d& edge_noise) const {
  std::vector<LineSegment> result;
  result.reserve(edges_.size());
  for (std::size_t k = 0; k < edges_.size(); ++k) result.push_back(world_edge(k, edge_noise));
  return result;
}

RigidObject RigidObject::updated(std::size_t k, const LineFeature& observed, const Eigen::Matrix2d& edge_noise) const {
  constexpr const char* kCaller = "RigidObject::updated";
  check_index(k, edges_.size(), kCaller);
  internal::require_finite(edge_noise, kCaller, "edge_noise");

  const LineFeature local = local_line(edges_[k]);
  const internal::TransformedLine h = internal::transform_line_raw(local.rho_m, local.phi_rad, pose_);
  const Eigen::Matrix<double, 2, 3>& jac = h.d_pose;
  const LineFeature predicted{h.rho_m, h.phi_rad, jac * pose_cov_ * jac.transpose()};
  const LineFeature measured{observed.rho_m, observed.phi_rad, observed.cov + edge_noise};
  // align_to picks z's representation next to h_k and checks that S = HPHᵀ + R is positive definite.
  const LineFeature z = internal::align_to(predicted, measured, kCaller).line;

  const Eigen::Vector2d nu(z.rho_m - predicted.rho_m, normalize_angle(z.phi_rad - predicted.phi_rad));
  const Eigen::Matrix2d& r = z.cov;
  const Eigen::Matrix2d s = predicted.cov + r;
  const Eigen::LLT<Eigen::Matrix2d> s_llt(0.5 * (s + s.transpose()));
  if (s_llt.info() != Eigen::Success)
    throw std::invalid_argument(std::string(kCaller) + ": innovation covariance is singular");
  // K = P Hᵀ S⁻¹, computed as (S⁻¹ H P)ᵀ since S and P are symmetric.
  const Eigen::Matrix<double, 3, 2> gain = s_llt.solve(jac * pose_cov_).transpose();
  const Eigen::Vector3d ds = gain * nu;
  const Eigen::Matrix3d i_kh = Eigen::Matrix3d::Identity() - gain * jac;
  const Eigen::Matrix3d p = i_kh * pose_cov_ * i_kh.transpose() + gain * r * gain.transpose();

  RigidObject result = *this;
  result.pose_ = Pose2D{pose_.x_m + ds.x(), pose_.y_m + ds.y(), normalize_angle(pose_.theta_rad + ds.z())};
  result.pose_cov_ = 0.5 * (p + p.transpose());
  return result;
}

}  // namespace wm::fusion
