#include "fusion/kalman/rigid_object.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

#include "fusion/geometry/angle.h"
#include "fusion/internal/line_algebra.h"
#include "tests/fusion/fusion_test_helpers.h"

namespace wm::fusion {
namespace {

constexpr double kPi = std::numbers::pi;

const Eigen::Matrix2d kNoNoise = Eigen::Matrix2d::Zero();
const Eigen::Matrix2d kEdgeNoise = Eigen::Vector2d(4e-4, 1e-4).asDiagonal();

// A 1.6 m × 0.8 m table centred on its origin, edges counter-clockwise: bottom, right, top, left.
std::vector<LocalEdge> table_edges() {
  const Eigen::Vector2d c[4] = {{-0.8, -0.4}, {0.8, -0.4}, {0.8, 0.4}, {-0.8, 0.4}};
  return {{c[0], c[1]}, {c[1], c[2]}, {c[2], c[3]}, {c[3], c[0]}};
}

RigidObject rotated_table() {
  return RigidObject(Pose2D{2.0, 1.0, 0.3}, Eigen::Vector3d(2.5e-3, 2.5e-3, 2.5e-3).asDiagonal(), table_edges());
}

Eigen::Vector3d as_vector(const Pose2D& p) { return {p.x_m, p.y_m, p.theta_rad}; }

// World (ρ, φ) of edge k at pose s, computed from the transformed endpoints only.
Eigen::Vector2d edge_line_from_points(const LocalEdge& edge, const Eigen::Vector3d& s, double reference_phi) {
  const Pose2D pose{s.x(), s.y(), s.z()};
  return testing::line_through(pose.transform_point(edge.p0), pose.transform_point(edge.p1), reference_phi);
}

double edge_angle(const LineSegment& s) { return std::atan2((s.p1() - s.p0()).y(), (s.p1() - s.p0()).x()); }

void expect_same_shape(const RigidObject& before, const RigidObject& after) {
  const auto a = before.world_edges(kNoNoise);
  const auto b = after.world_edges(kNoNoise);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_NEAR(a[k].length_m(), b[k].length_m(), 1e-9) << "edge " << k;
    const std::size_t next = (k + 1) % a.size();
    // Undirected: a world segment runs along its normalized line, which may flip when ρ crosses 0.
    const double angle_before = edge_angle(a[next]) - edge_angle(a[k]);
    const double angle_after = edge_angle(b[next]) - edge_angle(b[k]);
    EXPECT_NEAR(std::remainder(angle_after - angle_before, kPi), 0.0, 1e-9) << "edges " << k << ", " << next;
    // Corners stay shared: the end of one world edge is an end of the next.
    const double corner_gap = std::min({(b[k].p0() - b[next].p0()).norm(), (b[k].p0() - b[next].p1()).norm(),
                                        (b[k].p1() - b[next].p0()).norm(), (b[k].p1() - b[next].p1()).norm()});
    EXPECT_NEAR(corner_gap, 0.0, 1e-9);
  }
}

TEST(RigidObjectTest, MeasurementJacobianMatchesNumericDifferentiation) {
  const RigidObject table = rotated_table();
  for (std::size_t k = 0; k < table.edges().size(); ++k) {
    const LocalEdge& edge = table.edges()[k];
    const LineFeature local = LineSegment::from_points(edge.p0, edge.p1, Eigen::Matrix2d::Identity()).line;
    const internal::TransformedLine h = internal::transform_line_raw(local.rho_m, local.phi_rad, table.pose());
    const Eigen::Vector3d s = as_vector(table.pose());
    const auto f = [&](const Eigen::Vector3d& x) { return edge_line_from_points(edge, x, h.phi_rad); };
    const Eigen::Vector2d value = f(s);
    EXPECT_NEAR(h.rho_m, value(0), 1e-12);
    EXPECT_NEAR(h.phi_rad, value(1), 1e-12);
    const Eigen::Matrix<double, 2, 3> numeric = testing::numeric_jacobian<2>(f, s);
    EXPECT_NEAR((h.d_pose - numeric).cwiseAbs().maxCoeff(), 0.0, 1e-7) << "H\n" << h.d_pose << "\nnumeric\n" << numeric;
  }
}

TEST(RigidObjectTest, WorldEdgeCovarianceIsPosePropagatedPlusEdgeNoise) {
  const Eigen::Matrix3d pose_cov =
      (Eigen::Matrix3d() << 4e-3, 1e-3, 5e-4, 1e-3, 2e-3, -3e-4, 5e-4, -3e-4, 1e-3).finished();
  const RigidObject table(Pose2D{-3.0, 0.5, 2.9}, pose_cov, table_edges());
  const Eigen::Vector3d s = as_vector(table.pose());
  for (std::size_t k = 0; k < table.edges().size(); ++k) {
    const LineSegment world = table.world_edge(k, kEdgeNoise);
    EXPECT_GE(world.line.rho_m, 0.0);
    EXPECT_LE(world.t0_m, world.t1_m);
    const auto f = [&](const Eigen::Vector3d& x) {
      return edge_line_from_points(table.edges()[k], x, world.line.phi_rad);
    };
    const Eigen::Matrix<double, 2, 3> j = testing::numeric_jacobian<2>(f, s);
    const Eigen::Matrix2d expected = j * pose_cov * j.transpose() + kEdgeNoise;
    EXPECT_NEAR((world.line.cov - expected).cwiseAbs().maxCoeff(), 0.0, 1e-9 * expected.cwiseAbs().maxCoeff())
        << "edge " << k << "\n"
        << world.line.cov << "\nvs\n"
        << expected;
    // The endpoints are the local endpoints moved by the pose.
    const Eigen::Vector2d q0 = table.pose().transform_point(table.edges()[k].p0);
    const Eigen::Vector2d q1 = table.pose().transform_point(table.edges()[k].p1);
    EXPECT_NEAR(std::min((world.p0() - q0).norm(), (world.p0() - q1).norm()), 0.0, 1e-12);
    EXPECT_NEAR(std::min((world.p1() - q0).norm(), (world.p1() - q1).norm()), 0.0, 1e-12);
  }
  EXPECT_NEAR(table.world_edges(kNoNoise)[0].length_m(), 1.6, 1e-12);
  EXPECT_NEAR(table.world_edges(kNoNoise)[1].length_m(), 0.8, 1e-12);
}

TEST(RigidObjectTest, ShiftedEdgePullsThePoseAlongItsNormal) {
  const RigidObject table = rotated_table();
  const std::size_t k = 2;  // the long top edge
  const LineSegment predicted = table.world_edge(k, kEdgeNoise);
  LineFeature observed = predicted.line;
  observed.rho_m += 0.05;  // 5 cm along the normal
  observed.cov = Eigen::Vector2d(1e-4, 1e-4).asDiagonal();

  const RigidObject moved = table.updated(k, observed, kEdgeNoise);
  const Eigen::Vector2d n = predicted.line.normal();
  const Eigen::Vector2d d = predicted.line.direction();
  const Eigen::Vector2d shift(moved.pose().x_m - table.pose().x_m, moved.pose().y_m - table.pose().y_m);
  EXPECT_GT(shift.dot(n), 0.01);
  EXPECT_LT(shift.dot(n), 0.05);
  EXPECT_NEAR(shift.dot(d), 0.0, 1e-6);
  // The edge itself ends up between where it was predicted and where it was seen.
  const double new_rho = moved.world_edge(k, kEdgeNoise).line.rho_m;
  EXPECT_GT(new_rho, predicted.line.rho_m + 0.01);
  EXPECT_LT(new_rho, predicted.line.rho_m + 0.05);

  // Uncertainty only shrinks: P − P' is PSD, strictly along the normal, and unchanged along the edge.
  const Eigen::Matrix3d& before = table.pose_cov();
  const Eigen::Matrix3d& after = moved.pose_cov();
  EXPECT_GT(testing::min_eigenvalue(Eigen::Matrix3d(before - after)), -1e-15);
  EXPECT_LT(after.trace(), before.trace());
  const Eigen::Vector3d n3(n.x(), n.y(), 0.0), d3(d.x(), d.y(), 0.0);
  EXPECT_LT(n3.dot(after * n3), 0.5 * n3.dot(before * n3));
  EXPECT_NEAR(d3.dot(after * d3), d3.dot(before * d3), 1e-12);
  EXPECT_EQ(after, after.transpose());

  // *this is unchanged.
  EXPECT_EQ(as_vector(table.pose()), as_vector(rotated_table().pose()));
  EXPECT_EQ(table.pose_cov(), rotated_table().pose_cov());
  expect_same_shape(table, moved);
}

TEST(RigidObjectTest, UpdateMatchesTheKalmanFormulasByHand) {
  const RigidObject table = rotated_table();
  const std::size_t k = 1;
  const LineFeature local =
      LineSegment::from_points(table.edges()[k].p0, table.edges()[k].p1, Eigen::Matrix2d::Identity()).line;
  const internal::TransformedLine h = internal::transform_line_raw(local.rho_m, local.phi_rad, table.pose());
  const LineFeature observed{h.rho_m - 0.03, h.phi_rad + 0.02,
                             (Eigen::Matrix2d() << 2e-4, 1e-5, 1e-5, 3e-4).finished()};
  const RigidObject moved = table.updated(k, observed, kEdgeNoise);

  const Eigen::Matrix3d& p = table.pose_cov();
  const Eigen::Matrix2d r = observed.cov + kEdgeNoise;
  const Eigen::Matrix2d s = h.d_pose * p * h.d_pose.transpose() + r;
  const Eigen::Matrix<double, 3, 2> gain = p * h.d_pose.transpose() * s.inverse();
  const Eigen::Vector3d expected = as_vector(table.pose()) + gain * Eigen::Vector2d(-0.03, 0.02);
  const Eigen::Matrix3d expected_cov = (Eigen::Matrix3d::Identity() - gain * h.d_pose) * p;  // optimal-gain form
  EXPECT_NEAR((as_vector(moved.pose()) - expected).norm(), 0.0, 1e-14);
  EXPECT_NEAR((moved.pose_cov() - expected_cov).cwiseAbs().maxCoeff(), 0.0, 1e-15);
}

TEST(RigidObjectTest, ObservationInTheOtherRepresentationGivesTheSameUpdate) {
  const RigidObject table = rotated_table();
  LineFeature observed = table.world_edge(0, kNoNoise).line;
  observed.rho_m += 0.02;
  observed.phi_rad += 0.01;
  observed.cov = (Eigen::Matrix2d() << 1e-4, 2e-5, 2e-5, 1e-4).finished();
  const Eigen::Matrix2d f = Eigen::Vector2d(-1.0, 1.0).asDiagonal();
  const LineFeature other{-observed.rho_m, observed.phi_rad + kPi, f * observed.cov * f};
  const RigidObject a = table.updated(0, observed, kEdgeNoise);
  const RigidObject b = table.updated(0, other, kEdgeNoise);
  EXPECT_NEAR((as_vector(a.pose()) - as_vector(b.pose())).norm(), 0.0, 1e-14);
  EXPECT_NEAR((a.pose_cov() - b.pose_cov()).cwiseAbs().maxCoeff(), 0.0, 1e-17);
}

TEST(RigidObjectTest, RepeatedUpdatesKeepLengthsAndAnglesExactly) {
  RigidObject table = rotated_table();
  const RigidObject original = table;
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.03);
  for (int i = 0; i < 40; ++i) {
    const std::size_t k = static_cast<std::size_t>(i) % table.edges().size();
    LineFeature observed = table.world_edge(k, kNoNoise).line;
    observed.rho_m += noise(rng);
    observed.phi_rad += noise(rng);
    observed.cov = Eigen::Vector2d(1e-4, 1e-4).asDiagonal();
    table = table.updated(k, observed, kEdgeNoise);
  }
  expect_same_shape(original, table);
  EXPECT_GT(testing::min_eigenvalue(table.pose_cov()), 0.0);
}

TEST(RigidObjectTest, UpdateIsConsistentOverManyRandomTrials) {
  // NEES (s' − s_true)ᵀ P'⁻¹ (s' − s_true) of a consistent filter averages 3 (χ² with 3 dof). Its sample mean
  // over 2000 trials has σ = sqrt(6/2000) ≈ 0.055; the band below is about ±3.5σ.
  const Eigen::Matrix3d prior = Eigen::Vector3d(2.5e-3, 2.5e-3, 4e-4).asDiagonal();
  const Eigen::Matrix2d r = Eigen::Vector2d(1e-4, 1e-4).asDiagonal();
  const Eigen::Matrix3d prior_root = prior.llt().matrixL();
  const Eigen::Matrix2d r_root = r.llt().matrixL();
  const Pose2D truth{2.0, 1.0, 0.3};
  const RigidObject true_table(truth, Eigen::Matrix3d::Zero(), table_edges());
  std::mt19937 rng(2024);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int trials = 2000;
  double nees_sum = 0.0;
  double prior_nees_sum = 0.0;
  for (int trial = 0; trial < trials; ++trial) {
    const Eigen::Vector3d e0 = prior_root * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    const RigidObject estimate(Pose2D{truth.x_m + e0.x(), truth.y_m + e0.y(), truth.theta_rad + e0.z()}, prior,
                               table_edges());
    const std::size_t k = static_cast<std::size_t>(trial) % 4;
    LineFeature z = true_table.world_edge(k, kNoNoise).line;
    const Eigen::Vector2d v = r_root * Eigen::Vector2d(normal(rng), normal(rng));
    z.rho_m += v.x();
    z.phi_rad += v.y();
    z.cov = r;
    const RigidObject updated = estimate.updated(k, z, kNoNoise);
    Eigen::Vector3d e = as_vector(updated.pose()) - as_vector(truth);
    e.z() = normalize_angle(e.z());
    nees_sum += e.dot(updated.pose_cov().ldlt().solve(e));
    prior_nees_sum += e0.dot(prior.ldlt().solve(e0));
  }
  EXPECT_NEAR(prior_nees_sum / trials, 3.0, 0.2);  // sanity check of the sampling itself
  EXPECT_NEAR(nees_sum / trials, 3.0, 0.2);
}

TEST(RigidObjectTest, ZeroPoseCovarianceIsAcceptedAndStaysPut) {
  const RigidObject known(Pose2D{1.0, 2.0, 0.5}, Eigen::Matrix3d::Zero(), table_edges());
  LineFeature observed = known.world_edge(0, kNoNoise).line;
  observed.rho_m += 0.1;
  observed.cov = Eigen::Vector2d(1e-4, 1e-4).asDiagonal();
  const RigidObject same = known.updated(0, observed, kNoNoise);
  EXPECT_EQ(as_vector(same.pose()), as_vector(known.pose()));
  EXPECT_EQ(same.pose_cov(), Eigen::Matrix3d::Zero());
}

TEST(RigidObjectTest, ConstructorRejectsInvalidObjects) {
  const Eigen::Matrix3d ok = Eigen::Matrix3d::Identity() * 1e-3;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(RigidObject(Pose2D{}, ok, {}), std::invalid_argument);
  EXPECT_THROW(RigidObject(Pose2D{}, ok, {{{1.0, 1.0}, {1.0, 1.0 + 1e-10}}}), std::invalid_argument);
  EXPECT_THROW(RigidObject(Pose2D{}, ok, {{{nan, 1.0}, {1.0, 2.0}}}), std::invalid_argument);
  EXPECT_THROW(RigidObject(Pose2D{nan, 0.0, 0.0}, ok, table_edges()), std::invalid_argument);
  Eigen::Matrix3d asymmetric = ok;
  asymmetric(0, 1) = 1e-4;
  EXPECT_THROW(RigidObject(Pose2D{}, asymmetric, table_edges()), std::invalid_argument);
  EXPECT_THROW(RigidObject(Pose2D{}, Eigen::Vector3d(1e-3, -1e-3, 1e-3).asDiagonal(), table_edges()),
               std::invalid_argument);
  EXPECT_THROW(RigidObject(Pose2D{}, Eigen::Matrix3d::Constant(nan), table_edges()), std::invalid_argument);
}

TEST(RigidObjectTest, RejectsBadEdgeIndexAndInvalidObservations) {
  const RigidObject table = rotated_table();
  const LineFeature observed{1.0, 0.3, Eigen::Vector2d(1e-4, 1e-4).asDiagonal()};
  EXPECT_THROW(table.world_edge(4, kEdgeNoise), std::out_of_range);
  EXPECT_THROW(table.updated(4, observed, kEdgeNoise), std::out_of_range);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(table.updated(0, LineFeature{nan, 0.3, observed.cov}, kEdgeNoise), std::invalid_argument);
  EXPECT_THROW(table.updated(0, observed, Eigen::Matrix2d::Constant(nan)), std::invalid_argument);
  EXPECT_THROW(table.world_edge(0, Eigen::Matrix2d::Constant(nan)), std::invalid_argument);
  // Known pose and exact measurement: S = 0.
  const RigidObject known(Pose2D{}, Eigen::Matrix3d::Zero(), table_edges());
  EXPECT_THROW(known.updated(0, LineFeature{0.4, -kPi / 2.0}, kNoNoise), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
