#include "fusion/kalman/rigid_object.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "fusion/geometry/angle.h"
#include "fusion/internal/line_algebra.h"

namespace wm::fusion {
namespace {

constexpr double kMinEdgeLength = 1e-9;  // [m]
constexpr double kPi = std::numbers::pi;

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

Eigen::Matrix2d rotation(double angle_rad) { return Eigen::Rotation2Dd(angle_rad).toRotationMatrix(); }

// J: turns a vector by +90° (∂R(θ)v/∂θ = J R(θ) v).
const Eigen::Matrix2d kTurn = (Eigen::Matrix2d() << 0.0, -1.0, 1.0, 0.0).finished();

// The other representation of a line: (−ρ, φ+π), cov(ρ, φ) negated.
void flip(double& rho, double& phi, Eigen::Matrix2d& cov) {
  rho = -rho;
  phi += kPi;
  cov(0, 1) = -cov(0, 1);
  cov(1, 0) = -cov(1, 0);
}

// A world line (ρ_w, φ_w, C) expressed in the frame at `origin` turned by `theta`: φ = φ_w − θ,
// ρ = ρ_w − n(φ_w)·origin, C carried through J = [[1, ∂ρ/∂φ_w], [0, 1]] (exact: the map is linear in ρ_w).
LineFeature in_frame(const LineFeature& world, const Eigen::Vector2d& origin, double theta) {
  const double c = std::cos(world.phi_rad), s = std::sin(world.phi_rad);
  Eigen::Matrix2d j;
  j << 1.0, origin.x() * s - origin.y() * c, 0.0, 1.0;
  return LineFeature{world.rho_m - origin.x() * c - origin.y() * s, world.phi_rad - theta,
                     j * world.cov * j.transpose()};
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

Eigen::Vector2d RigidObject::local_centroid() const {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  double weight = 0.0;
  for (const LocalEdge& e : edges_) {
    const double length = (e.p1 - e.p0).norm();
    sum += length * 0.5 * (e.p0 + e.p1);
    weight += length;
  }
  return sum / weight;  // weight > 0: every edge is longer than kMinEdgeLength
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
  const EdgeObservation one{k, observed, edge_noise};
  return updated(std::span<const EdgeObservation>(&one, 1));
}

RigidObject RigidObject::updated(std::span<const EdgeObservation> observations,
                                 const RigidUpdateOptions& options) const {
  constexpr const char* kCaller = "RigidObject::updated";
  if (observations.empty()) throw std::invalid_argument(std::string(kCaller) + ": no observations");
  if (options.start && !finite(*options.start))
    throw std::invalid_argument(std::string(kCaller) + ": start pose is not finite");
  if (options.max_iterations == 0) throw std::invalid_argument(std::string(kCaller) + ": max_iterations is 0");

  // The frame F: at the edges' centroid, turned by θ₀. In it the current pose is u = (0, 0, 0) and the lever arm
  // of a turn is the object's own size, not its distance from the world origin.
  const Eigen::Vector2d c = local_centroid();
  const double theta0 = pose_.theta_rad;
  const Eigen::Matrix2d r0 = rotation(theta0);
  const Eigen::Vector2d w0 = Eigen::Vector2d(pose_.x_m, pose_.y_m) + r0 * c;
  // Prior over u: B P Bᵀ, B = ∂u/∂s = [[R₀ᵀ, J c], [0, 0, 1]].
  Eigen::Matrix3d b = Eigen::Matrix3d::Zero();
  b.topLeftCorner<2, 2>() = r0.transpose();
  b.block<2, 1>(0, 2) = kTurn * c;
  b(2, 2) = 1.0;
  const Eigen::Matrix3d prior = b * pose_cov_ * b.transpose();

  Eigen::Vector3d u = Eigen::Vector3d::Zero();
  if (options.start) {
    const Pose2D& s = *options.start;
    const double alpha = normalize_angle(s.theta_rad - theta0);
    const Eigen::Vector2d ws = Eigen::Vector2d(s.x_m, s.y_m) + rotation(theta0 + alpha) * c;
    u << r0.transpose() * (ws - w0), alpha;
  }

  // Measurements in F, each in the representation of its edge's local line carried along (h below), which is
  // also the one the edge's own noise turns with.
  const auto m = static_cast<Eigen::Index>(observations.size());
  Eigen::VectorXd z(2 * m);
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(2 * m, 2 * m);
  std::vector<double> rho_c(observations.size()), phi_o(observations.size());
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const EdgeObservation& obs = observations[i];
    check_index(obs.edge, edges_.size(), kCaller);
    internal::require_finite(obs.edge_noise, kCaller, "edge_noise");
    if (!std::isfinite(obs.observed.rho_m) || !std::isfinite(obs.observed.phi_rad))
      throw std::invalid_argument(std::string(kCaller) + ": observed line " + std::to_string(i) + " is not finite");
    internal::require_finite(obs.observed.cov, kCaller, "observed.cov");
    const LineFeature local = local_line(edges_[obs.edge]);
    phi_o[i] = local.phi_rad;
    rho_c[i] = local.rho_m - local.normal().dot(c);

    LineFeature seen = in_frame(obs.observed, w0, theta0);
    const double phi_start = phi_o[i] + u.z();
    if (std::abs(normalize_angle(seen.phi_rad - phi_start)) > 0.5 * kPi) flip(seen.rho_m, seen.phi_rad, seen.cov);
    seen.phi_rad = phi_start + normalize_angle(seen.phi_rad - phi_start);

    const LineFeature drawn = world_edge(obs.edge, Eigen::Matrix2d::Zero()).line;
    LineFeature noise = in_frame(LineFeature{drawn.rho_m, drawn.phi_rad, obs.edge_noise}, w0, theta0);
    if (std::abs(normalize_angle(noise.phi_rad - phi_o[i])) > 0.5 * kPi) flip(noise.rho_m, noise.phi_rad, noise.cov);

    const auto at = 2 * static_cast<Eigen::Index>(i);
    z.segment<2>(at) << seen.rho_m, seen.phi_rad;
    r.block<2, 2>(at, at) = 0.5 * (seen.cov + seen.cov.transpose()) + 0.5 * (noise.cov + noise.cov.transpose());
  }

  // Iterated EKF (Gauss–Newton on the prior plus all lines): u⁺ = K (ν + H u), K = P Hᵀ (H P Hᵀ + R)⁻¹, with
  // h_k(u) = [ρ_kᶜ + u_x cos φ + u_y sin φ; φ], φ = φ_kᵒ + α, linearised at the latest u.
  Eigen::MatrixXd h(2 * m, 3);
  Eigen::MatrixXd gain(3, 2 * m);
  for (std::size_t iteration = 0;; ++iteration) {
    Eigen::VectorXd nu(2 * m);
    for (std::size_t i = 0; i < observations.size(); ++i) {
      const auto at = 2 * static_cast<Eigen::Index>(i);
      const double phi = phi_o[i] + u.z();
      const double cs = std::cos(phi), sn = std::sin(phi);
      h.row(at) << cs, sn, -u.x() * sn + u.y() * cs;
      h.row(at + 1) << 0.0, 0.0, 1.0;
      nu(at) = z(at) - (rho_c[i] + u.x() * cs + u.y() * sn);
      nu(at + 1) = normalize_angle(z(at + 1) - phi);
    }
    Eigen::MatrixXd s = h * prior * h.transpose() + r;
    s = (0.5 * (s + s.transpose())).eval();
    const Eigen::LLT<Eigen::MatrixXd> s_llt(s);
    if (s_llt.info() != Eigen::Success)
      throw std::invalid_argument(std::string(kCaller) + ": innovation covariance is singular");
    // K = P Hᵀ S⁻¹, computed as (S⁻¹ H P)ᵀ since S and P are symmetric.
    gain = s_llt.solve(h * prior).transpose();
    const Eigen::Vector3d next = gain * (nu + h * u);
    const bool converged = (next - u).cwiseAbs().maxCoeff() < options.tolerance;
    u = next;
    if (converged || iteration + 1 >= options.max_iterations) break;
  }
  const Eigen::Matrix3d i_kh = Eigen::Matrix3d::Identity() - gain * h;
  const Eigen::Matrix3d p_u = i_kh * prior * i_kh.transpose() + gain * r * gain.transpose();

  // Back to the object's origin: θ = θ₀ + α, t = w₀ + R₀ u_xy − R(θ) c; P = D P_u Dᵀ, D = ∂s/∂u.
  const double theta = theta0 + u.z();
  const Eigen::Vector2d rc = rotation(theta) * c;
  const Eigen::Vector2d t = w0 + r0 * u.head<2>() - rc;
  Eigen::Matrix3d d = Eigen::Matrix3d::Zero();
  d.topLeftCorner<2, 2>() = r0;
  d.block<2, 1>(0, 2) = -kTurn * rc;
  d(2, 2) = 1.0;
  const Eigen::Matrix3d p = d * p_u * d.transpose();

  RigidObject result = *this;
  result.pose_ = Pose2D{t.x(), t.y(), normalize_angle(theta)};
  result.pose_cov_ = 0.5 * (p + p.transpose());
  return result;
}

RigidObject RigidObject::with_move_allowed(const Pose2D& found) const {
  if (!finite(found)) throw std::invalid_argument("RigidObject::with_move_allowed: pose is not finite");
  const Eigen::Vector2d c = local_centroid();
  const Eigen::Vector2d moved = found.transform_point(c) - pose_.transform_point(c);
  const double turned = normalize_angle(found.theta_rad - pose_.theta_rad);
  // The move is diagonal about the centroid; the pose is the origin's, t = w − R(θ) c.
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();
  g.block<2, 1>(0, 2) = -kTurn * rotation(pose_.theta_rad) * c;
  const Eigen::Matrix3d q = Eigen::Vector3d(moved.x() * moved.x(), moved.y() * moved.y(), turned * turned).asDiagonal();
  RigidObject result = *this;
  const Eigen::Matrix3d p = pose_cov_ + g * q * g.transpose();
  result.pose_cov_ = 0.5 * (p + p.transpose());
  return result;
}

namespace {

// One observed segment as the shape search sees it.
struct Seen {
  Eigen::Vector2d p0, p1, dir;
  double length;
};

// Where two lines (point, unit direction) cross; nullopt when (nearly) parallel.
std::optional<Eigen::Vector2d> crossing(const Eigen::Vector2d& pa, const Eigen::Vector2d& da, const Eigen::Vector2d& pb,
                                        const Eigen::Vector2d& db) {
  const double det = da.x() * db.y() - da.y() * db.x();
  if (std::abs(det) < 1e-9) return std::nullopt;
  const Eigen::Vector2d w = pb - pa;
  return Eigen::Vector2d(pa + (w.x() * db.y() - w.y() * db.x()) / det * da);
}

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

struct Verdict {
  std::vector<std::optional<std::size_t>> edge_of;
  std::size_t explained = 0;
  double length_m = 0.0;
  double sum_sq_m2 = 0.0;  // of the explained ends' offsets
};

// Which edge, at `pose`, each segment lies on: direction, both ends across the line, both ends along it.
Verdict verify(const std::vector<LocalEdge>& edges, const Pose2D& pose, const std::vector<Seen>& seen,
               const ShapeFitOptions& o) {
  Verdict v;
  v.edge_of.assign(seen.size(), std::nullopt);
  const double max_sin = std::sin(o.max_angle_rad);
  std::vector<double> best(seen.size(), 0.0);
  for (std::size_t k = 0; k < edges.size(); ++k) {
    const Eigen::Vector2d e0 = pose.transform_point(edges[k].p0), e1 = pose.transform_point(edges[k].p1);
    const double length = (e1 - e0).norm();
    const Eigen::Vector2d d = (e1 - e0) / length, n(d.y(), -d.x());
    for (std::size_t i = 0; i < seen.size(); ++i) {
      const Seen& s = seen[i];
      if (std::abs(cross(s.dir, d)) > max_sin) continue;
      const double a = n.dot(s.p0 - e0), b = n.dot(s.p1 - e0);
      const double worst = std::max(std::abs(a), std::abs(b));
      if (worst > o.max_offset_m) continue;
      const double ta = d.dot(s.p0 - e0), tb = d.dot(s.p1 - e0);
      if (std::min(ta, tb) < -o.max_overhang_m || std::max(ta, tb) > length + o.max_overhang_m) continue;
      if (v.edge_of[i] && worst >= best[i]) continue;
      v.edge_of[i] = k;
      best[i] = worst;
    }
  }
  for (std::size_t i = 0; i < seen.size(); ++i) {
    if (!v.edge_of[i]) continue;
    const LocalEdge& e = edges[*v.edge_of[i]];
    const Eigen::Vector2d e0 = pose.transform_point(e.p0), d = (pose.transform_point(e.p1) - e0).normalized();
    const Eigen::Vector2d n(d.y(), -d.x());
    ++v.explained;
    v.length_m += seen[i].length;
    v.sum_sq_m2 += std::pow(n.dot(seen[i].p0 - e0), 2) + std::pow(n.dot(seen[i].p1 - e0), 2);
  }
  return v;
}

// Gauss–Newton on the segments' ends against their edges' lines, turning about the centroid `c` (object frame).
Pose2D refine(const std::vector<LocalEdge>& edges, Pose2D pose, const Eigen::Vector2d& c, const std::vector<Seen>& seen,
              const std::vector<std::pair<std::size_t, std::size_t>>& pairs) {
  for (int iteration = 0; iteration < 5; ++iteration) {
    const Eigen::Vector2d w = pose.transform_point(c);
    // A whisper of damping keeps parallel-only pairs (no fix along them) where they were.
    Eigen::Matrix3d a = 1e-9 * Eigen::Matrix3d::Identity();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (const auto& [i, k] : pairs) {
      const Eigen::Vector2d e0 = pose.transform_point(edges[k].p0);
      const Eigen::Vector2d d = (pose.transform_point(edges[k].p1) - e0).normalized(), n(d.y(), -d.x());
      for (const Eigen::Vector2d& p : {seen[i].p0, seen[i].p1}) {
        const double residual = n.dot(p - e0);
        const Eigen::Vector3d j(-n.x(), -n.y(), -n.dot(kTurn * (p - w)));
        a += j * j.transpose();
        g += j * residual;
      }
    }
    const Eigen::Vector3d step = -a.ldlt().solve(g);
    if (!step.allFinite()) return pose;
    const Eigen::Vector2d t = rotation(step.z()) * (Eigen::Vector2d(pose.x_m, pose.y_m) - w) + w + step.head<2>();
    pose = Pose2D{t.x(), t.y(), normalize_angle(pose.theta_rad + step.z())};
    if (step.cwiseAbs().maxCoeff() < 1e-9) break;
  }
  return pose;
}

std::vector<std::pair<std::size_t, std::size_t>> pairs_of(const std::vector<std::optional<std::size_t>>& edge_of) {
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (std::size_t i = 0; i < edge_of.size(); ++i)
    if (edge_of[i]) pairs.emplace_back(i, *edge_of[i]);
  return pairs;
}

}  // namespace

std::optional<ShapeFit> find_by_shape(const RigidObject& object, std::span<const LineSegment> observed,
                                      const ShapeFitOptions& o) {
  const auto& edges = object.edges();
  if (edges.size() > o.max_edges || observed.size() < o.min_explained) return std::nullopt;
  std::vector<Seen> seen;
  seen.reserve(observed.size());
  for (std::size_t i = 0; i < observed.size(); ++i) {
    const Eigen::Vector2d p0 = observed[i].p0(), p1 = observed[i].p1();
    if (!p0.allFinite() || !p1.allFinite())
      throw std::invalid_argument("find_by_shape: segment " + std::to_string(i) + " is not finite");
    const double length = (p1 - p0).norm();
    seen.push_back({p0, p1, length > 0.0 ? Eigen::Vector2d((p1 - p0) / length) : Eigen::Vector2d::UnitX(), length});
  }
  std::vector<std::size_t> seeds(seen.size());
  for (std::size_t i = 0; i < seeds.size(); ++i) seeds[i] = i;
  std::stable_sort(seeds.begin(), seeds.end(), [&](auto a, auto b) { return seen[a].length > seen[b].length; });
  seeds.resize(std::min(seeds.size(), o.max_seeds));

  const Eigen::Vector2d c = object.local_centroid();
  const Eigen::Vector2d centre_now = object.pose().transform_point(c);
  double radius = 0.0;
  for (const auto& e : edges) radius = std::max({radius, (e.p0 - c).norm(), (e.p1 - c).norm()});
  const double min_sin = std::sin(o.min_crossing_rad);

  std::optional<Pose2D> best_pose;
  Verdict best;
  double best_move = 0.0;
  for (std::size_t x = 0; x < seeds.size(); ++x)
    for (std::size_t y = x + 1; y < seeds.size(); ++y) {
      const Seen& a = seen[seeds[x]];
      const Seen& b = seen[seeds[y]];
      if (std::abs(cross(a.dir, b.dir)) < min_sin) continue;
      const auto seen_corner = crossing(a.p0, a.dir, b.p0, b.dir);
      if (!seen_corner) continue;
      for (std::size_t i = 0; i < edges.size(); ++i)
        for (std::size_t j = 0; j < edges.size(); ++j) {
          if (i == j) continue;
          const Eigen::Vector2d di = edges[i].p1 - edges[i].p0, dj = edges[j].p1 - edges[j].p0;
          // An edge's view is no longer than the edge (plus what may run past its ends).
          if (a.length > di.norm() + 2 * o.max_overhang_m || b.length > dj.norm() + 2 * o.max_overhang_m) continue;
          const Eigen::Vector2d ui = di.normalized(), uj = dj.normalized();
          if (std::abs(cross(ui, uj)) < min_sin) continue;
          const double turn_a = std::atan2(a.dir.y(), a.dir.x()) - std::atan2(ui.y(), ui.x());
          const double turn_b = std::atan2(b.dir.y(), b.dir.x()) - std::atan2(uj.y(), uj.x());
          // Undirected lines: the two turns agree modulo π.
          const double disagree = 0.5 * normalize_angle(2.0 * (turn_b - turn_a));
          if (std::abs(disagree) > 2.0 * o.max_angle_rad) continue;
          const auto edge_corner = crossing(edges[i].p0, ui, edges[j].p0, uj);
          if (!edge_corner) continue;
          const double mean_turn = turn_a + disagree * b.length / (a.length + b.length);
          for (const double turn : {mean_turn, mean_turn + kPi}) {
            const Eigen::Vector2d t = *seen_corner - rotation(turn) * *edge_corner;
            Pose2D pose{t.x(), t.y(), normalize_angle(turn)};
            if ((pose.transform_point(c) - centre_now).norm() > o.max_shift_m) continue;
            pose = refine(edges, pose, c, seen, {{seeds[x], i}, {seeds[y], j}});
            Verdict v = verify(edges, pose, seen, o);
            if (!v.edge_of[seeds[x]] || !v.edge_of[seeds[y]] || v.explained < o.min_explained) continue;
            const double move = (pose.transform_point(c) - centre_now).norm() +
                                radius * std::abs(normalize_angle(pose.theta_rad - object.pose().theta_rad));
            if (move > o.max_shift_m + radius * kPi) continue;
            const bool better = !best_pose || v.length_m > best.length_m + 1e-6 ||
                                (v.length_m > best.length_m - 1e-6 && move < best_move);
            if (!better) continue;
            best_pose = pose;
            best = std::move(v);
            best_move = move;
          }
        }
    }
  if (!best_pose) return std::nullopt;
  // Once more on every explained segment; what it then explains is the answer.
  const Pose2D pose = refine(edges, *best_pose, c, seen, pairs_of(best.edge_of));
  Verdict v = verify(edges, pose, seen, o);
  if (v.explained < o.min_explained || (pose.transform_point(c) - centre_now).norm() > o.max_shift_m)
    return std::nullopt;
  ShapeFit fit;
  fit.pose = pose;
  fit.explained = v.explained;
  fit.explained_length_m = v.length_m;
  fit.rms_offset_m = std::sqrt(v.sum_sq_m2 / (2.0 * static_cast<double>(v.explained)));
  fit.edge_of = std::move(v.edge_of);
  return fit;
}

}  // namespace wm::fusion
