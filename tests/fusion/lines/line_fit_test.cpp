#include "fusion/lines/line_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "fusion/geometry/angle.h"
#include "tests/fusion/fusion_test_helpers.h"

namespace wm::fusion {
namespace {

constexpr double kPi = std::numbers::pi;

// Points ρn + t·d for the given t values.
std::vector<Eigen::Vector2d> points_on(double rho, double phi, const std::vector<double>& ts) {
  const LineFeature line{rho, phi};
  std::vector<Eigen::Vector2d> points;
  for (double t : ts) points.push_back(rho * line.normal() + t * line.direction());
  return points;
}

std::vector<double> linspace(double a, double b, int n) {
  std::vector<double> v;
  for (int i = 0; i < n; ++i) v.push_back(a + (b - a) * i / (n - 1));
  return v;
}

LineFeature fit_isotropic(const std::vector<Eigen::Vector2d>& points, double sigma) {
  const std::vector<double> sigmas(points.size(), sigma);
  return fit_line(points, sigmas);
}

// docs/fusion.md §2 closed form for isotropic σ_i, in the representation of `line`:
// var φ = 1/Σw(t−t̄)², var ρ = 1/W + t_c²·var φ, cov(ρ, φ) = t_c·var φ, t_c = coordinate of the weighted centroid.
Eigen::Matrix2d closed_form_cov(const LineFeature& line, const std::vector<Eigen::Vector2d>& points,
                                const std::vector<double>& sigmas) {
  double w_sum = 0.0;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    w_sum += 1.0 / (sigmas[i] * sigmas[i]);
    centroid += points[i] / (sigmas[i] * sigmas[i]);
  }
  centroid /= w_sum;
  const double t_c = line.coordinate_along(centroid);
  double s_tt = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double dt = line.coordinate_along(points[i]) - t_c;
    s_tt += dt * dt / (sigmas[i] * sigmas[i]);
  }
  const double var_phi = 1.0 / s_tt;
  return (Eigen::Matrix2d() << 1.0 / w_sum + t_c * t_c * var_phi, t_c * var_phi, t_c * var_phi, var_phi).finished();
}

// Sample covariance of the fitted (ρ, φ) around the truth over `trials` noisy copies of `points`.
Eigen::Matrix2d monte_carlo_cov(const LineFeature& truth, const std::vector<Eigen::Vector2d>& points,
                                const std::vector<Eigen::Matrix2d>& covs, int trials, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<Eigen::Matrix2d> roots;
  for (const auto& c : covs) roots.push_back(c.llt().matrixL());
  std::vector<Eigen::Vector2d> noisy(points.size());
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  Eigen::Matrix2d sum_sq = Eigen::Matrix2d::Zero();
  for (int trial = 0; trial < trials; ++trial) {
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector2d z(normal(rng), normal(rng));
      noisy[i] = points[i] + roots[i] * z;
    }
    const LineFeature fit = fit_line(noisy, covs);
    const Eigen::Vector2d e(fit.rho_m - truth.rho_m, normalize_angle(fit.phi_rad - truth.phi_rad));
    sum += e;
    sum_sq += e * e.transpose();
  }
  const Eigen::Vector2d mean = sum / trials;
  return (sum_sq - trials * mean * mean.transpose()) / (trials - 1);
}

void expect_cov_close(const Eigen::Matrix2d& analytic, const Eigen::Matrix2d& sampled, double rel_tol) {
  EXPECT_NEAR(sampled(0, 0) / analytic(0, 0), 1.0, rel_tol) << "var rho\n" << analytic << "\nvs\n" << sampled;
  EXPECT_NEAR(sampled(1, 1) / analytic(1, 1), 1.0, rel_tol) << "var phi\n" << analytic << "\nvs\n" << sampled;
  const double scale = std::sqrt(analytic(0, 0) * analytic(1, 1));
  EXPECT_NEAR((sampled(0, 1) - analytic(0, 1)) / scale, 0.0, rel_tol) << "cov\n" << analytic << "\nvs\n" << sampled;
}

TEST(FitLineTest, FitsNoiseFreePointsExactly) {
  const auto points = points_on(3.0, 0.7, linspace(-2.0, 2.5, 15));
  const LineFeature fit = fit_isotropic(points, 0.01);
  EXPECT_NEAR(fit.rho_m, 3.0, 1e-12);
  EXPECT_NEAR(fit.phi_rad, 0.7, 1e-12);
}

TEST(FitLineTest, FitsTwoPointsExactly) {
  const std::vector<Eigen::Vector2d> points = {{1.0, 2.0}, {3.0, 2.0}};
  const LineFeature fit = fit_isotropic(points, 0.01);
  EXPECT_NEAR(fit.rho_m, 2.0, 1e-14);
  EXPECT_NEAR(fit.phi_rad, kPi / 2.0, 1e-14);
}

TEST(FitLineTest, FitsVerticalLinesOnBothSidesOfTheOrigin) {
  const std::vector<double> ys = linspace(-1.0, 4.0, 11);
  std::vector<Eigen::Vector2d> right, left;
  for (double y : ys) {
    right.emplace_back(2.0, y);
    left.emplace_back(-2.0, y);
  }
  const LineFeature r = fit_isotropic(right, 0.01);
  EXPECT_NEAR(r.rho_m, 2.0, 1e-12);
  EXPECT_NEAR(r.phi_rad, 0.0, 1e-12);
  // The closed form yields α = 0 and r = −2 here: the result must be flipped to ρ = 2, φ = π.
  const LineFeature l = fit_isotropic(left, 0.01);
  EXPECT_NEAR(l.rho_m, 2.0, 1e-12);
  EXPECT_NEAR(l.phi_rad, kPi, 1e-12);
}

TEST(FitLineTest, FitsHorizontalLineBelowTheOrigin) {
  const auto points = points_on(1.0, -kPi / 2.0, linspace(-3.0, 3.0, 9));
  const LineFeature fit = fit_isotropic(points, 0.02);
  EXPECT_NEAR(fit.rho_m, 1.0, 1e-12);
  EXPECT_NEAR(fit.phi_rad, -kPi / 2.0, 1e-12);
}

TEST(FitLineTest, LineThroughTheOriginHasZeroRhoAndAValidNormal) {
  const auto points = points_on(0.0, 0.4, linspace(-2.0, 3.0, 12));
  const LineFeature fit = fit_isotropic(points, 0.01);
  EXPECT_GE(fit.rho_m, 0.0);
  EXPECT_NEAR(fit.rho_m, 0.0, 1e-12);
  // φ is 0.4 or 0.4 − π; both describe the line.
  EXPECT_NEAR(std::sin(fit.phi_rad - 0.4), 0.0, 1e-12);
  for (const auto& p : points) EXPECT_NEAR(fit.signed_distance(p), 0.0, 1e-12);
}

TEST(FitLineTest, PhiFlipsByPiWhenTheLineCrossesTheOrigin) {
  const LineFeature above = fit_isotropic(points_on(1e-3, 0.4, linspace(-2.0, 3.0, 12)), 0.01);
  const LineFeature below = fit_isotropic(points_on(-1e-3, 0.4, linspace(-2.0, 3.0, 12)), 0.01);
  EXPECT_NEAR(above.rho_m, 1e-3, 1e-12);
  EXPECT_NEAR(above.phi_rad, 0.4, 1e-12);
  EXPECT_NEAR(below.rho_m, 1e-3, 1e-12);
  EXPECT_NEAR(below.phi_rad, 0.4 - kPi, 1e-12);
}

TEST(FitLineTest, CovarianceMatchesClosedFormForIsotropicPoints) {
  // Grid-cell style σ_i = cell / P_occ with P_occ in [0.6, 1] (docs/fusion.md §2), points off-centre so that
  // cov(ρ, φ) = t_c·var φ is far from zero.
  const double phis[] = {0.3, kPi, -2.0};  // −2.0 and π come out of the closed form with r < 0 and get flipped
  for (double phi : phis) {
    const auto points = points_on(2.5, phi, linspace(1.0, 3.0, 41));
    std::vector<double> sigmas;
    for (std::size_t i = 0; i < points.size(); ++i) sigmas.push_back(0.05 / (0.6 + 0.4 * ((i * 7) % 10) / 9.0));
    const LineFeature fit = fit_line(points, sigmas);
    EXPECT_NEAR(fit.rho_m, 2.5, 1e-12);
    EXPECT_NEAR(normalize_angle(fit.phi_rad - phi), 0.0, 1e-12);
    const Eigen::Matrix2d expected = closed_form_cov(fit, points, sigmas);
    EXPECT_NEAR((fit.cov - expected).cwiseAbs().maxCoeff(), 0.0, 1e-12 * expected.cwiseAbs().maxCoeff())
        << "phi " << phi << "\n"
        << fit.cov << "\nvs\n"
        << expected;
    EXPECT_GT(std::abs(fit.cov(0, 1)), 0.5 * std::sqrt(fit.cov(0, 0) * fit.cov(1, 1)));
  }
}

TEST(FitLineTest, MonteCarloCovarianceMatchesAnalyticForIsotropicPoints) {
  const LineFeature truth{2.0, 0.9};
  const auto points = points_on(truth.rho_m, truth.phi_rad, linspace(0.5, 2.5, 41));
  std::vector<Eigen::Matrix2d> covs;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double sigma = 0.05 / (0.6 + 0.4 * ((i * 3) % 7) / 6.0);
    covs.push_back(sigma * sigma * Eigen::Matrix2d::Identity());
  }
  const LineFeature analytic = fit_line(points, covs);
  const Eigen::Matrix2d sampled = monte_carlo_cov(truth, points, covs, 20000, 12345u);
  expect_cov_close(analytic.cov, sampled, 0.04);
}

TEST(FitLineTest, MonteCarloCovarianceMatchesAnalyticForLaserPoints) {
  // A wall seen by a laser at the origin: range noise σ_r along the beam, bearing noise r·σ_θ across it.
  const LineFeature truth{3.0, -0.4};
  const auto points = points_on(truth.rho_m, truth.phi_rad, linspace(-2.5, 1.5, 30));
  std::vector<Eigen::Matrix2d> covs;
  for (const auto& p : points) {
    const double r = p.norm();
    covs.push_back(testing::rotated_cov(0.01 * 0.01, std::pow(r * 0.004, 2), std::atan2(p.y(), p.x())));
  }
  const LineFeature analytic = fit_line(points, covs);
  EXPECT_NEAR(analytic.rho_m, truth.rho_m, 1e-12);
  EXPECT_NEAR(analytic.phi_rad, truth.phi_rad, 1e-12);
  const Eigen::Matrix2d sampled = monte_carlo_cov(truth, points, covs, 20000, 987u);
  expect_cov_close(analytic.cov, sampled, 0.04);
}

TEST(FitLineTest, WeightsPointsByTheirVarianceAlongTheNormal) {
  // Two precise points define the line; a third is off the line but very noisy across it, so it barely counts.
  const std::vector<Eigen::Vector2d> points = {{0.0, 1.0}, {2.0, 1.0}, {1.0, 1.5}};
  const std::vector<double> sigmas = {0.001, 0.001, 1.0};
  const LineFeature fit = fit_line(points, sigmas);
  EXPECT_NEAR(fit.rho_m, 1.0, 1e-5);
  EXPECT_NEAR(fit.phi_rad, kPi / 2.0, 1e-5);
  // A covariance elongated along the line (small across it) is trusted as much as a tight isotropic one.
  const std::vector<Eigen::Matrix2d> covs = {1e-6 * Eigen::Matrix2d::Identity(), 1e-6 * Eigen::Matrix2d::Identity(),
                                             testing::rotated_cov(1.0, 1e-6, 0.0)};
  const LineFeature elongated = fit_line(points, covs);
  EXPECT_NEAR(elongated.rho_m, 1.0 + 0.5 / 3.0, 1e-6);  // equal weights: centroid y = 7/6
}

TEST(FitLineTest, RejectsBadInput) {
  const std::vector<Eigen::Vector2d> two = {{0.0, 0.0}, {1.0, 0.0}};
  const std::vector<double> ok = {0.01, 0.01};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fit_line(std::vector<Eigen::Vector2d>{{0.0, 0.0}}, std::vector<double>{0.01}), std::invalid_argument);
  EXPECT_THROW(fit_line(two, std::vector<double>{0.01}), std::invalid_argument);
  EXPECT_THROW(fit_line(two, std::vector<double>{0.01, 0.0}), std::invalid_argument);
  EXPECT_THROW(fit_line(two, std::vector<double>{0.01, nan}), std::invalid_argument);
  EXPECT_THROW(fit_line(std::vector<Eigen::Vector2d>{{0.0, 0.0}, {nan, 0.0}}, ok), std::invalid_argument);
  EXPECT_THROW(fit_line(std::vector<Eigen::Vector2d>{{1.0, 1.0}, {1.0, 1.0}}, ok), std::invalid_argument);
  const std::vector<Eigen::Matrix2d> not_pd = {Eigen::Matrix2d::Identity(), Eigen::Vector2d(1.0, -1.0).asDiagonal()};
  EXPECT_THROW(fit_line(two, not_pd), std::invalid_argument);
  // The corners of a square: every direction fits equally well.
  const std::vector<Eigen::Vector2d> square = {{0.0, 0.0}, {1.0, 0.0}, {1.0, 1.0}, {0.0, 1.0}};
  EXPECT_THROW(fit_line(square, std::vector<double>(4, 0.01)), std::invalid_argument);
  try {
    fit_line(two, std::vector<double>{0.01});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fit_line"), std::string::npos);
  }
}

}  // namespace
}  // namespace wm::fusion
