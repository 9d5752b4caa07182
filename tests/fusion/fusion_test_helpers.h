#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <numbers>

#include "fusion/geometry/angle.h"

// Test-only helpers for the fusion tests: independent (geometric, numeric) reference computations.
namespace wm::fusion::testing {

/// Central-difference Jacobian of f: R^N -> R^M at x (f returns an Eigen vector of size M).
template <int M, int N, typename F>
Eigen::Matrix<double, M, N> numeric_jacobian(const F& f, const Eigen::Matrix<double, N, 1>& x, double step = 1e-6) {
  Eigen::Matrix<double, M, N> j;
  for (int i = 0; i < N; ++i) {
    Eigen::Matrix<double, N, 1> hi = x, lo = x;
    hi(i) += step;
    lo(i) -= step;
    j.col(i) = (f(hi) - f(lo)) / (2.0 * step);
  }
  return j;
}

/// (ρ, φ) of the line through a and b, in the representation whose φ is within π/2 of reference_phi (φ unwrapped
/// next to it), computed from the points only — an independent reference for the fusion formulas.
inline Eigen::Vector2d line_through(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double reference_phi) {
  const Eigen::Vector2d d = (b - a).normalized();
  Eigen::Vector2d n(d.y(), -d.x());
  if (n.dot(Eigen::Vector2d(std::cos(reference_phi), std::sin(reference_phi))) < 0.0) n = -n;
  const double phi = reference_phi + normalize_angle(std::atan2(n.y(), n.x()) - reference_phi);
  return {n.dot(a), phi};
}

template <typename Matrix>
double min_eigenvalue(const Matrix& m) {
  return Eigen::SelfAdjointEigenSolver<Matrix>(0.5 * (m + m.transpose()), Eigen::EigenvaluesOnly)
      .eigenvalues()
      .minCoeff();
}

/// Rotation of the diagonal covariance diag(a, b) by angle [rad].
inline Eigen::Matrix2d rotated_cov(double a, double b, double angle) {
  const Eigen::Matrix2d r =
      (Eigen::Matrix2d() << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle)).finished();
  return r * Eigen::Vector2d(a, b).asDiagonal() * r.transpose();
}

}  // namespace wm::fusion::testing
