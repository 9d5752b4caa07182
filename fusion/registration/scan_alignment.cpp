#include "fusion/registration/scan_alignment.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace wm::fusion {
namespace {

using Vector3 = Eigen::Vector3d;
using Matrix3 = Eigen::Matrix3d;
using Matrix23 = Eigen::Matrix<double, 2, 3>;
using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

// One scan line paired with one map line at the pose so far, linearised: the ends' signed distances to the map line,
// their Jacobian over the pose (x, y, θ), and their noise from the two lines (the pose's part is kept apart).
struct Pair {
  Eigen::Vector2d residual;
  Matrix23 jacobian;
  Eigen::Matrix2d noise;            // of the scan line and the map line, as if independent: for the gate
  Eigen::Matrix2d sensor_noise;     // of the scan line alone
  double reference_offset_var = 0;  // the map line's variance across it, between the pair's ends [m²]
  double reference_angle_var = 0;   // and of its direction [rad²]
};

// Variance across a line at coordinates t0, t1 along it, from its (ρ, φ) covariance: a point that stays where it is
// lies δρ − t·δφ off the line that moved, so the ends' covariance is A C Aᵀ with rows (1, −t).
Eigen::Matrix2d across_line(const LineFeature& line, double t0, double t1) {
  Eigen::Matrix2d a;
  a << 1, -t0, 1, -t1;
  return a * line.cov * a.transpose();
}

std::optional<Pair> linearise(const LineSegment& local, const Pose2D& pose, const AlignmentReference& reference,
                              double min_overlap_share) {
  const Eigen::Vector2d q[2] = {local.p0(), local.p1()};
  const Eigen::Vector2d position(pose.x_m, pose.y_m);
  const Eigen::Vector2d w[2] = {pose.transform_point(q[0]), pose.transform_point(q[1])};
  const LineFeature& ref = reference.segment.line;
  const Eigen::Vector2d n = ref.normal();

  // The scan sees the face toward it: the normal from the line to the sensor must agree with the reference's facing.
  if (reference.facing_rad) {
    const double side = n.dot(position) - ref.rho_m;
    const Eigen::Vector2d toward_sensor = side >= 0 ? n : Eigen::Vector2d(-n);
    const Eigen::Vector2d facing(std::cos(*reference.facing_rad), std::sin(*reference.facing_rad));
    if (toward_sensor.dot(facing) <= 0) return std::nullopt;
  }
  const double a0 = ref.coordinate_along(w[0]), a1 = ref.coordinate_along(w[1]);
  const double overlap =
      std::min(std::max(a0, a1), reference.segment.t1_m) - std::max(std::min(a0, a1), reference.segment.t0_m);
  if (overlap < min_overlap_share * local.length_m()) return std::nullopt;

  Pair pair;
  for (int k = 0; k < 2; ++k) {
    pair.residual(k) = ref.signed_distance(w[k]);
    const Eigen::Vector2d lever = w[k] - position;  // ∂w/∂θ = the lever turned by 90°
    pair.jacobian.row(k) << n.x(), n.y(), n.dot(Eigen::Vector2d(-lever.y(), lever.x()));
  }
  Eigen::Matrix2d b;  // ∂d/∂(ρ, φ) of the reference: (−1, t along it)
  b << -1, a0, -1, a1;
  pair.sensor_noise = across_line(local.line, local.t0_m, local.t1_m);
  pair.noise = pair.sensor_noise + b * ref.cov * b.transpose();
  pair.reference_offset_var = across_line(ref, 0.5 * (a0 + a1), 0.5 * (a0 + a1))(0, 0);
  pair.reference_angle_var = ref.cov(1, 1);
  return pair;
}

double chi2(const Pair& pair, const Matrix3& pose_cov) {
  const Eigen::Matrix2d s = pair.jacobian * pose_cov * pair.jacobian.transpose() + pair.noise;
  return pair.residual.dot(s.ldlt().solve(pair.residual));
}

// An axis-aligned box [lo, hi] [m].
struct Box {
  Eigen::Vector2d lo, hi;
  bool overlaps(const Box& other) const {
    return (lo.array() <= other.hi.array()).all() && (other.lo.array() <= hi.array()).all();
  }
};

Box box_of(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double margin) {
  return {a.cwiseMin(b).array() - margin, a.cwiseMax(b).array() + margin};
}

// The one reference each long enough scan line lies on at `pose` (spread `cov`), unambiguous pairs only.
std::vector<Pair> pair_lines(const std::vector<LineSegment>& local, const Pose2D& pose, const Matrix3& cov,
                             const std::vector<AlignmentReference>& references, const std::vector<Box>& reference_boxes,
                             const ScanAlignmentOptions& options) {
  std::vector<Pair> pairs;
  // A scan line's ends move by at most a few σ of the pose: map lines outside that reach are not looked at (the χ²
  // gate would refuse them; the box test is cheaper than the gate).
  const double sigma_xy = std::sqrt(std::max({cov(0, 0), cov(1, 1), 0.0}));
  const double sigma_theta = std::sqrt(std::max(cov(2, 2), 0.0));
  for (const auto& segment : local) {
    if (segment.length_m() < options.min_segment_length_m) continue;
    const double range = std::max(segment.p0().norm(), segment.p1().norm());
    const Box reach = box_of(pose.transform_point(segment.p0()), pose.transform_point(segment.p1()),
                             alignment_reach_m(sigma_xy, sigma_theta, range));
    std::optional<Pair> best, second;
    double best_chi2 = std::numeric_limits<double>::infinity(), second_chi2 = best_chi2;
    for (std::size_t r = 0; r < references.size(); ++r) {
      if (!reach.overlaps(reference_boxes[r])) continue;
      const auto& reference = references[r];
      auto pair = linearise(segment, pose, reference, options.min_overlap_share);
      if (!pair) continue;
      const double c = chi2(*pair, cov);
      if (!(c <= options.pair_chi2)) continue;
      if (c < best_chi2) {
        second = std::move(best);
        second_chi2 = best_chi2;
        best = std::move(pair);
        best_chi2 = c;
      } else if (c < second_chi2) {
        second = std::move(pair);
        second_chi2 = c;
      }
    }
    if (!best) continue;
    if (second && second_chi2 < options.ambiguity_ratio * best_chi2) {
      const Eigen::Vector2d apart = best->residual - second->residual;
      const double sigma0 = std::sqrt(best->noise(0, 0)), sigma1 = std::sqrt(best->noise(1, 1));
      const double same = options.same_surface_sigmas;
      if (std::abs(apart(0)) > same * sigma0 || std::abs(apart(1)) > same * sigma1) continue;
    }
    pairs.push_back(std::move(*best));
  }
  return pairs;
}

double median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("align_scan_lines: ") + what);
}

}  // namespace

ScanAlignment align_scan_lines(const std::vector<LineSegment>& local, const Pose2D& posted_pose,
                               const Eigen::Matrix3d& posted_cov, const std::vector<AlignmentReference>& references,
                               const ScanAlignmentOptions& options) {
  require(std::isfinite(posted_pose.x_m) && std::isfinite(posted_pose.y_m) && std::isfinite(posted_pose.theta_rad),
          "the pose is not finite");
  require(posted_cov.allFinite(), "the covariance is not finite");
  require(posted_cov.isApprox(posted_cov.transpose(), 1e-9) || posted_cov.isZero(), "the covariance is not symmetric");
  ScanAlignment result{posted_pose, posted_cov, 0, false};
  if (posted_cov.isZero()) return result;  // an exact pose
  if (std::max(posted_cov(0, 0), posted_cov(1, 1)) > options.max_posted_sigma_m * options.max_posted_sigma_m ||
      posted_cov(2, 2) > options.max_posted_sigma_rad * options.max_posted_sigma_rad)
    return result;  // a guess
  const Eigen::SelfAdjointEigenSolver<Matrix3> eigen(posted_cov);
  require(eigen.eigenvalues().minCoeff() >= -1e-12 * std::max(1.0, eigen.eigenvalues().maxCoeff()),
          "the covariance is not positive semi-definite");

  // A direction the robot is certain of (zero variance) stays where it was posted: a tiny variance, a huge weight.
  const Matrix3 prior_information = (posted_cov + 1e-12 * Matrix3::Identity()).inverse();
  const Vector3 posted(posted_pose.x_m, posted_pose.y_m, posted_pose.theta_rad);
  // The state: the sensor pose, and the error of the map's frame where the scan is (the map's lines there share it:
  // they were placed by poses with errors of their own, so their noise is not independent from pair to pair and
  // twenty pairs know the pose relative to the map, not twenty times better relative to the world).
  Vector6 state = Vector6::Zero();
  state.head<3>() = posted;
  Matrix6 cov = Matrix6::Zero();
  cov.topLeftCorner<3, 3>() = posted_cov;
  std::size_t pairs_used = 0;
  std::vector<Box> reference_boxes;
  reference_boxes.reserve(references.size());
  for (const auto& reference : references)
    reference_boxes.push_back(box_of(reference.segment.p0(), reference.segment.p1(), 0.0));
  for (int pass = 0; pass < options.iterations; ++pass) {
    // Pairs are made where the scan lies against the map: the pose less the map's error.
    const Vector3 relative = state.head<3>() - state.tail<3>();
    const Matrix3 relative_cov = cov.topLeftCorner<3, 3>() + cov.bottomRightCorner<3, 3>() -
                                 cov.topRightCorner<3, 3>() - cov.bottomLeftCorner<3, 3>();
    const auto pairs = pair_lines(local, Pose2D{relative(0), relative(1), relative(2)}, relative_cov, references,
                                  reference_boxes, options);
    if (pairs.size() < options.min_pairs) return result;
    std::vector<double> offset_vars, angle_vars;
    for (const auto& pair : pairs) {
      offset_vars.push_back(pair.reference_offset_var);
      angle_vars.push_back(pair.reference_angle_var);
    }
    const Matrix3 map_cov = Eigen::Vector3d(median(offset_vars), median(offset_vars), median(angle_vars)).asDiagonal();
    // Gauss-Newton on the prior, the map's error and the pairs, linearised at the state so far (an iterated EKF
    // update): a pair's ends move with the pose and against the map's error.
    Matrix6 information = Matrix6::Zero();
    information.topLeftCorner<3, 3>() = prior_information;
    information.bottomRightCorner<3, 3>() = (map_cov + 1e-12 * Matrix3::Identity()).inverse();
    Vector6 gradient = Vector6::Zero();
    gradient.head<3>() = prior_information * (state.head<3>() - posted);
    gradient.tail<3>() = information.bottomRightCorner<3, 3>() * state.tail<3>();
    for (const auto& pair : pairs) {
      Eigen::Matrix<double, 2, 6> jacobian;
      jacobian << pair.jacobian, -pair.jacobian;
      const Eigen::Matrix2d weight = pair.sensor_noise.inverse();
      information += jacobian.transpose() * weight * jacobian;
      gradient += jacobian.transpose() * weight * pair.residual;
    }
    const Eigen::LDLT<Matrix6> solver(information);
    const Vector6 step = solver.solve(gradient);
    state -= step;
    cov = solver.solve(Matrix6::Identity());
    cov = 0.5 * (cov + cov.transpose());
    pairs_used = pairs.size();
    // Converged: a step of under 0.1 mm and 1 µrad would pair the same lines again.
    if (step.head<2>().norm() < 1e-4 && step.segment<2>(3).norm() < 1e-4 && std::abs(step(2)) < 1e-6 &&
        std::abs(step(5)) < 1e-6)
      break;
  }
  const Vector3 step = state.head<3>() - posted;
  if (!(step.dot(prior_information * step) <= options.max_correction_chi2)) return result;
  return {Pose2D{state(0), state(1), state(2)}, cov.topLeftCorner<3, 3>(), pairs_used, true};
}

double alignment_reach_m(double sigma_xy_m, double sigma_theta_rad, double range_m) {
  return 5 * (sigma_xy_m + range_m * sigma_theta_rad) + 0.05;
}

}  // namespace wm::fusion
