#include "fusion/kalman/rigid_object.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <iostream>
#include <limits>
#include <numbers>
#include <random>
#include <span>
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
  // Along the edge only at second order: the observation's (ρ, φ) correlation about the world origin turns the
  // table a hair, and the iteration follows the turned edge.
  EXPECT_NEAR(shift.dot(d), 0.0, 5e-4);
  // The edge itself ends up between where it was predicted and where it was seen.
  const double new_rho = moved.world_edge(k, kEdgeNoise).line.rho_m;
  EXPECT_GT(new_rho, predicted.line.rho_m + 0.01);
  EXPECT_LT(new_rho, predicted.line.rho_m + 0.05);

  // Uncertainty only shrinks: P − P' is PSD, strictly along the normal, and (nearly) unchanged along the edge.
  const Eigen::Matrix3d& before = table.pose_cov();
  const Eigen::Matrix3d& after = moved.pose_cov();
  EXPECT_GT(testing::min_eigenvalue(Eigen::Matrix3d(before - after)), -1e-15);
  EXPECT_LT(after.trace(), before.trace());
  const Eigen::Vector3d n3(n.x(), n.y(), 0.0), d3(d.x(), d.y(), 0.0);
  EXPECT_LT(n3.dot(after * n3), 0.5 * n3.dot(before * n3));
  EXPECT_NEAR(d3.dot(after * d3), d3.dot(before * d3), 1e-4 * d3.dot(before * d3));
  EXPECT_EQ(after, after.transpose());

  // *this is unchanged.
  EXPECT_EQ(as_vector(table.pose()), as_vector(rotated_table().pose()));
  EXPECT_EQ(table.pose_cov(), rotated_table().pose_cov());
  expect_same_shape(table, moved);
}

// One iteration about a table whose centroid is the world origin is the textbook EKF of docs/fusion.md §4 (the
// frame at the centroid is then the world frame turned by θ).
TEST(RigidObjectTest, OneIterationAtTheOriginIsTheKalmanUpdateByHand) {
  const RigidObject table(Pose2D{0.0, 0.0, 0.3}, Eigen::Vector3d(2.5e-3, 2.5e-3, 2.5e-3).asDiagonal(), table_edges());
  const std::size_t k = 1;
  const LineFeature local =
      LineSegment::from_points(table.edges()[k].p0, table.edges()[k].p1, Eigen::Matrix2d::Identity()).line;
  const internal::TransformedLine h = internal::transform_line_raw(local.rho_m, local.phi_rad, table.pose());
  const LineFeature observed{h.rho_m - 0.03, h.phi_rad + 0.02,
                             (Eigen::Matrix2d() << 2e-4, 1e-5, 1e-5, 3e-4).finished()};
  RigidUpdateOptions once;
  once.max_iterations = 1;
  const std::vector<EdgeObservation> lines = {{k, observed, kEdgeNoise}};
  const RigidObject moved = table.updated(lines, once);

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

// --- A 1.2 m × 0.8 m table 25 m from the world origin, moved, seen again by simulated scans. ---

constexpr double kDeg = kPi / 180.0;
const Pose2D kFarPose{24.0, 7.0, 0.2};
const Eigen::Matrix3d kDefaultPoseCov = Eigen::Vector3d(2.5e-3, 2.5e-3, 2.5e-3).asDiagonal();

// Counter-clockwise, centred on its origin: bottom, right, top, left.
std::vector<LocalEdge> small_table_edges() {
  const Eigen::Vector2d c[4] = {{-0.6, -0.4}, {0.6, -0.4}, {0.6, 0.4}, {-0.6, 0.4}};
  return {{c[0], c[1]}, {c[1], c[2]}, {c[2], c[3]}, {c[3], c[0]}};
}

// Covariance of a line known to σ_offset across the segment's midpoint and σ_angle in direction (the world's
// midpoint form).
Eigen::Matrix2d midpoint_cov(const LineSegment& s, double sigma_offset_m, double sigma_angle_rad) {
  const double t_mid = 0.5 * (s.t0_m + s.t1_m);
  const Eigen::Matrix2d j = (Eigen::Matrix2d() << 1.0, t_mid, 0.0, 1.0).finished();
  return j * Eigen::Vector2d(sigma_offset_m * sigma_offset_m, sigma_angle_rad * sigma_angle_rad).asDiagonal() *
         j.transpose();
}

// What the world adds for the drawing's own error: 2 cm across the edge's middle, 0.005 rad.
Eigen::Matrix2d drawing_noise(const RigidObject& body, std::size_t k) {
  return midpoint_cov(body.world_edge(k, kNoNoise), 0.02, 0.005);
}

struct View {
  std::size_t edge;
  LineSegment seen;
};

// The sides of the table standing at `truth` that a robot at `viewpoint` sees, each up to 5 cm short at either end,
// its ends with 1 cm noise, and the covariance that noise gives.
std::vector<View> views_of(const Pose2D& truth, const Eigen::Vector2d& viewpoint, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> trim(0.0, 0.05);
  std::vector<View> views;
  const auto edges = small_table_edges();
  for (std::size_t k = 0; k < edges.size(); ++k) {
    const Eigen::Vector2d a = truth.transform_point(edges[k].p0), b = truth.transform_point(edges[k].p1);
    const Eigen::Vector2d d = (b - a).normalized();
    if (Eigen::Vector2d(d.y(), -d.x()).dot(viewpoint - a) <= 0.0) continue;
    const Eigen::Vector2d p = a + trim(rng) * d + Eigen::Vector2d(noise(rng), noise(rng));
    const Eigen::Vector2d q = b - trim(rng) * d + Eigen::Vector2d(noise(rng), noise(rng));
    LineSegment s = LineSegment::from_points(p, q, Eigen::Matrix2d::Identity());
    s.line.cov = midpoint_cov(s, 0.01 / std::sqrt(2.0), 0.01 * std::sqrt(2.0) / s.length_m());
    views.push_back({k, s});
  }
  return views;
}

Pose2D moved_pose(double shift_m, double turn_rad) {
  return {kFarPose.x_m + shift_m * std::cos(0.5), kFarPose.y_m + shift_m * std::sin(0.5),
          kFarPose.theta_rad + turn_rad};
}

// Scan s from the diagonal at 45° + s·90°, 3 m from the table: two sides each.
Eigen::Vector2d viewpoint_of(const Pose2D& truth, int scan) {
  const double bearing = kPi / 4 + scan * kPi / 2;
  return Eigen::Vector2d(truth.x_m, truth.y_m) + 3.0 * Eigen::Vector2d(std::cos(bearing), std::sin(bearing));
}

struct PoseError {
  double position_m, angle_rad;
};
PoseError error_of(const Pose2D& estimate, const Pose2D& truth) {
  return {std::hypot(estimate.x_m - truth.x_m, estimate.y_m - truth.y_m),
          std::abs(normalize_angle(estimate.theta_rad - truth.theta_rad))};
}

TEST(RigidObjectTest, OneEdgeAtATimeFromTheOldPoseEndsNearTheTruth) {
  for (const double shift : {0.1, 0.3, 0.5})
    for (const double turn : {5.0, 10.0, 20.0}) {
      const Pose2D truth = moved_pose(shift, turn * kDeg);
      RigidObject table(kFarPose, kDefaultPoseCov, small_table_edges());
      std::mt19937 rng(5);
      for (int scan = 0; scan < 8; ++scan)
        for (const View& v : views_of(truth, viewpoint_of(truth, scan), rng))
          table = table.updated(v.edge, v.seen.line, drawing_noise(table, v.edge));
      const PoseError e = error_of(table.pose(), truth);
      std::cout << "[figures] one edge at a time, moved " << shift << " m, " << turn << " deg: ends "
                << e.position_m * 100 << " cm, " << e.angle_rad / kDeg << " deg from the truth\n";
      EXPECT_LT(e.position_m, 0.03) << shift << " m, " << turn << " deg";
      EXPECT_LT(e.angle_rad, 1.0 * kDeg) << shift << " m, " << turn << " deg";
    }
}

// The world's path: the first scan finds the carried table by its shape (the pose found starts the iteration, the
// covariance widened to cover the move), every scan is one joint update of the sides it sees.
TEST(RigidObjectTest, AMovedTableFoundByShapeEndsWithinThreeCentimetresAndOneDegree) {
  for (const double shift : {0.1, 0.3, 0.5})
    for (const double turn : {5.0, 10.0, 20.0}) {
      const Pose2D truth = moved_pose(shift, turn * kDeg);
      RigidObject table(kFarPose, kDefaultPoseCov, small_table_edges());
      std::mt19937 rng(5);
      for (int scan = 0; scan < 8; ++scan) {
        const auto views = views_of(truth, viewpoint_of(truth, scan), rng);
        std::vector<EdgeObservation> lines;
        RigidUpdateOptions how;
        if (scan == 0) {
          std::vector<LineSegment> seen;
          for (const View& v : views) seen.push_back(v.seen);
          const auto fit = find_by_shape(table, seen);
          ASSERT_TRUE(fit.has_value()) << shift << " m, " << turn << " deg";
          EXPECT_EQ(fit->explained, views.size());
          for (std::size_t i = 0; i < views.size(); ++i) EXPECT_EQ(fit->edge_of[i], views[i].edge);
          const PoseError e = error_of(fit->pose, truth);
          EXPECT_LT(e.position_m, 0.03);
          EXPECT_LT(e.angle_rad, 2.0 * kDeg);
          table = table.with_move_allowed(fit->pose);
          how.start = fit->pose;
        }
        for (const View& v : views) lines.push_back({v.edge, v.seen.line, drawing_noise(table, v.edge)});
        table = table.updated(lines, how);
      }
      const PoseError e = error_of(table.pose(), truth);
      std::cout << "[figures] found by shape, joint updates, moved " << shift << " m, " << turn << " deg: ends "
                << e.position_m * 100 << " cm, " << e.angle_rad / kDeg << " deg from the truth\n";
      EXPECT_LT(e.position_m, 0.03) << shift << " m, " << turn << " deg";
      EXPECT_LT(e.angle_rad, 1.0 * kDeg) << shift << " m, " << turn << " deg";
      EXPECT_GT(testing::min_eigenvalue(table.pose_cov()), 0.0);
    }
}

// Without the shape search, from the old pose and its default covariance, joint iterated updates only.
TEST(RigidObjectTest, JointIteratedUpdatesFromTheOldPoseEndNearTheTruth) {
  for (const double shift : {0.1, 0.3, 0.5})
    for (const double turn : {5.0, 10.0, 20.0}) {
      const Pose2D truth = moved_pose(shift, turn * kDeg);
      RigidObject table(kFarPose, kDefaultPoseCov, small_table_edges());
      std::mt19937 rng(5);
      for (int scan = 0; scan < 8; ++scan) {
        std::vector<EdgeObservation> lines;
        for (const View& v : views_of(truth, viewpoint_of(truth, scan), rng))
          lines.push_back({v.edge, v.seen.line, drawing_noise(table, v.edge)});
        table = table.updated(lines);
      }
      const PoseError e = error_of(table.pose(), truth);
      std::cout << "[figures] joint updates from the old pose, moved " << shift << " m, " << turn << " deg: ends "
                << e.position_m * 100 << " cm, " << e.angle_rad / kDeg << " deg from the truth\n";
      // The old pose stays in the estimate as a prior worth a fraction of one scan.
      EXPECT_LT(e.position_m, 0.03) << shift << " m, " << turn << " deg";
      EXPECT_LT(e.angle_rad, 1.0 * kDeg) << shift << " m, " << turn << " deg";
    }
}

// The same object, the same move and the same views, once at the origin and once 25 m away: the same update
// (what went wrong before: the lever arm of (ρ, φ) about the world origin).
TEST(RigidObjectTest, UpdateDoesNotDependOnTheDistanceFromTheOrigin) {
  const Pose2D near_pose{0.0, 0.0, 0.2};
  const Pose2D far_pose = kFarPose;
  const Pose2D move{0.25, -0.1, 10.0 * kDeg};  // in the object's frame
  const auto moved = [&](const Pose2D& p) {
    const Eigen::Vector2d t = p.transform_point({move.x_m, move.y_m});
    return Pose2D{t.x(), t.y(), p.theta_rad + move.theta_rad};
  };
  Pose2D result[2];
  for (int which = 0; which < 2; ++which) {
    const Pose2D start = which == 0 ? near_pose : far_pose;
    const RigidObject table(start, kDefaultPoseCov, small_table_edges());
    const RigidObject truth(moved(start), Eigen::Matrix3d::Zero(), small_table_edges());
    std::vector<EdgeObservation> lines;
    for (std::size_t k : {0u, 1u}) {
      LineSegment seen = truth.world_edge(k, kNoNoise);
      seen.line.cov = midpoint_cov(seen, 0.007, 0.01);
      lines.push_back({k, seen.line, drawing_noise(table, k)});
    }
    const RigidObject after = table.updated(lines);
    // The result relative to the start pose.
    const Eigen::Vector2d rel = start.inverse_transform_point({after.pose().x_m, after.pose().y_m});
    result[which] = Pose2D{rel.x(), rel.y(), normalize_angle(after.pose().theta_rad - start.theta_rad)};
  }
  EXPECT_NEAR(result[0].x_m, result[1].x_m, 1e-8);
  EXPECT_NEAR(result[0].y_m, result[1].y_m, 1e-8);
  EXPECT_NEAR(result[0].theta_rad, result[1].theta_rad, 1e-9);
  // Two crossing sides, exact lines, one update: most of the way; the prior (5 cm, 0.05 rad) keeps some of the old
  // pose.
  std::cout << "[figures] one joint update, move (0.25 m, -0.1 m, 10 deg): (" << result[1].x_m << ", " << result[1].y_m
            << ", " << result[1].theta_rad / kDeg << " deg)\n";
  EXPECT_NEAR(result[1].x_m, move.x_m, 0.05);
  EXPECT_NEAR(result[1].y_m, move.y_m, 0.05);
  EXPECT_NEAR(result[1].theta_rad, move.theta_rad, 1.5 * kDeg);
}

TEST(RigidObjectTest, WidenedForAMoveTheCovarianceCoversIt) {
  const RigidObject table(kFarPose, kDefaultPoseCov, small_table_edges());
  const Pose2D found = moved_pose(0.3, 10.0 * kDeg);
  const RigidObject wide = table.with_move_allowed(found);
  EXPECT_EQ(as_vector(wide.pose()), as_vector(table.pose()));
  EXPECT_NEAR(wide.pose_cov()(2, 2), kDefaultPoseCov(2, 2) + std::pow(10.0 * kDeg, 2), 1e-12);
  // The centroid is the origin here: its move is the pose's.
  EXPECT_NEAR(wide.pose_cov()(0, 0), kDefaultPoseCov(0, 0) + std::pow(found.x_m - kFarPose.x_m, 2), 1e-12);
  EXPECT_NEAR(wide.pose_cov()(1, 1), kDefaultPoseCov(1, 1) + std::pow(found.y_m - kFarPose.y_m, 2), 1e-12);
  EXPECT_GE(testing::min_eigenvalue(Eigen::Matrix3d(wide.pose_cov() - table.pose_cov())), -1e-15);
  // An object whose frame is far from its edges: the turn's share moves its origin.
  std::vector<LocalEdge> offset = small_table_edges();
  for (auto& e : offset) {
    e.p0 += Eigen::Vector2d(10.0, 0.0);
    e.p1 += Eigen::Vector2d(10.0, 0.0);
  }
  const RigidObject far_frame(Pose2D{0.0, 0.0, 0.0}, kDefaultPoseCov, offset);
  EXPECT_NEAR(far_frame.local_centroid().x(), 10.0, 1e-12);
  const RigidObject turned = far_frame.with_move_allowed(Pose2D{0.0, 0.0, 0.1});
  // Turning the frame by 0.1 rad carries the centroid 1 m; the origin's y variance takes that and the turn's lever
  // (10 m × 0.1 rad).
  EXPECT_GT(turned.pose_cov()(1, 1), kDefaultPoseCov(1, 1) + 0.5 * 100.0 * 0.01);
}

TEST(RigidObjectTest, IteratedUpdateOfAnObjectFarFromItsFrameTurnsAboutItsCentroid) {
  // The table drawn 10 m from its frame's origin: a turn about that origin would sweep it 1.7 m per 10°.
  std::vector<LocalEdge> offset = small_table_edges();
  for (auto& e : offset) {
    e.p0 += Eigen::Vector2d(10.0, 0.0);
    e.p1 += Eigen::Vector2d(10.0, 0.0);
  }
  const RigidObject table(Pose2D{14.0, 7.0, 0.2}, kDefaultPoseCov, offset);
  const RigidObject truth(Pose2D{14.0, 7.0, 0.2 + 2.0 * kDeg}, Eigen::Matrix3d::Zero(), offset);
  std::vector<EdgeObservation> lines;
  for (std::size_t k : {0u, 1u, 2u}) {
    LineSegment seen = truth.world_edge(k, kNoNoise);
    seen.line.cov = midpoint_cov(seen, 0.007, 0.01);
    lines.push_back({k, seen.line, kNoNoise});
  }
  RigidObject estimate = table;
  for (int i = 0; i < 5; ++i) estimate = estimate.updated(lines);
  const Eigen::Vector2d c = table.local_centroid();
  EXPECT_NEAR((estimate.pose().transform_point(c) - truth.pose().transform_point(c)).norm(), 0.0, 0.01);
  EXPECT_NEAR(normalize_angle(estimate.pose().theta_rad - truth.pose().theta_rad), 0.0, 0.2 * kDeg);
}

TEST(RigidObjectTest, FindByShapeKeepsTheTurnClosestToTheCurrentPose) {
  // A rectangle matches itself turned by half a turn; the pose found is the one near the current pose.
  const RigidObject table(kFarPose, kDefaultPoseCov, small_table_edges());
  const Pose2D truth = moved_pose(0.3, 10.0 * kDeg);
  std::mt19937 rng(9);
  std::vector<LineSegment> seen;
  for (const View& v : views_of(truth, viewpoint_of(truth, 0), rng)) seen.push_back(v.seen);
  const auto fit = find_by_shape(table, seen);
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT(std::abs(normalize_angle(fit->pose.theta_rad - truth.theta_rad)), 2.0 * kDeg);
  EXPECT_LT(fit->rms_offset_m, 0.02);
  // Too far (beyond max_shift_m) or a single view: nothing.
  ShapeFitOptions tight;
  tight.max_shift_m = 0.1;
  EXPECT_FALSE(find_by_shape(table, seen, tight).has_value());
  EXPECT_FALSE(find_by_shape(table, std::span<const LineSegment>(seen.data(), 1)).has_value());
}

TEST(RigidObjectTest, FindByShapeDoesNotTakeAWallBesideTheObjectForIt) {
  const RigidObject table(kFarPose, kDefaultPoseCov, small_table_edges());
  // A 6 m wall 2 cm outside the top side, and a 3 m wall across the right side's line 2 cm outside it: each is a
  // line of a side, but much longer than the side.
  const auto make = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    LineSegment s = LineSegment::from_points(a, b, Eigen::Matrix2d::Identity());
    s.line.cov = midpoint_cov(s, 0.007, 0.002);
    return s;
  };
  const std::vector<LineSegment> walls = {
      make(kFarPose.transform_point({-3.0, 0.42}), kFarPose.transform_point({3.0, 0.42})),
      make(kFarPose.transform_point({0.62, -1.5}), kFarPose.transform_point({0.62, 1.5}))};
  EXPECT_FALSE(find_by_shape(table, walls).has_value());
  // Beside the table's own bottom side, seen as it stands: the wall is left out of what the fit explains.
  std::vector<LineSegment> seen = walls;
  seen.push_back(make(kFarPose.transform_point({-0.55, -0.4}), kFarPose.transform_point({0.55, -0.4})));
  seen.push_back(make(kFarPose.transform_point({-0.6, -0.35}), kFarPose.transform_point({-0.6, 0.35})));
  const auto fit = find_by_shape(table, seen);
  ASSERT_TRUE(fit.has_value());
  EXPECT_FALSE(fit->edge_of[0].has_value());
  EXPECT_FALSE(fit->edge_of[1].has_value());
  EXPECT_EQ(fit->explained, 2u);
  EXPECT_LT(error_of(fit->pose, kFarPose).position_m, 0.005);
}

TEST(RigidObjectTest, JointUpdateRejectsBadInput) {
  const RigidObject table = rotated_table();
  const LineFeature observed{1.0, 0.3, Eigen::Vector2d(1e-4, 1e-4).asDiagonal()};
  EXPECT_THROW(table.updated(std::span<const EdgeObservation>{}), std::invalid_argument);
  const std::vector<EdgeObservation> bad_edge = {{0, observed, kNoNoise}, {7, observed, kNoNoise}};
  EXPECT_THROW(table.updated(bad_edge), std::out_of_range);
  RigidUpdateOptions how;
  how.start = Pose2D{std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0};
  const std::vector<EdgeObservation> one = {{0, observed, kNoNoise}};
  EXPECT_THROW(table.updated(one, how), std::invalid_argument);
  std::vector<LineSegment> nan_segment(2, LineSegment::from_points({0, 0}, {1, 0}, Eigen::Matrix2d::Identity()));
  nan_segment[1].t1_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(find_by_shape(table, nan_segment), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
