#include "fusion/lines/scan_lines.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>

#include "fusion/kalman/line_map.h"
#include "fusion/lines/line_fit.h"

namespace wm::fusion {
namespace {

struct Piece {
  std::size_t first;  // index of the first point
  std::size_t last;   // index one past the last point
};

// σ of point i perpendicular to the direction `normal` [m].
double normal_sigma(const Eigen::Matrix2d& q, const Eigen::Vector2d& normal) {
  return std::sqrt(normal.dot(q * normal));
}

// The sums the step and bend tests share, built once per piece: prefix sums of its points (about its first point,
// for precision) and of their outer products, so that the scatter of any run of the piece costs O(1), and the largest
// σ of its points across the piece's line.
class PieceSums {
 public:
  PieceSums(const std::vector<Eigen::Vector2d>& points, const std::vector<Eigen::Matrix2d>& covs, Piece piece,
            const Eigen::Vector2d& normal)
      : first_(piece.first),
        sum_(piece.last - piece.first + 1, Eigen::Vector2d::Zero()),
        sum_sq_(piece.last - piece.first + 1, Eigen::Matrix2d::Zero()) {
    const Eigen::Vector2d origin = points[piece.first];
    for (std::size_t i = 0; i + piece.first < piece.last; ++i) {
      const Eigen::Vector2d p = points[piece.first + i] - origin;
      sum_[i + 1] = sum_[i] + p;
      sum_sq_[i + 1] = sum_sq_[i] + p * p.transpose();
      sigma_ = std::max(sigma_, normal_sigma(covs[piece.first + i], normal));
    }
  }

  std::size_t first() const { return first_; }
  std::size_t size() const { return sum_.size() - 1; }
  double sigma() const { return sigma_; }  // the largest σ across the line [m]
  // The mean of the piece's points a..b−1 (counted from its first point), about its first point.
  Eigen::Vector2d mean(std::size_t a, std::size_t b) const { return (sum_[b] - sum_[a]) / static_cast<double>(b - a); }
  // Σ (p − p̄)(p − p̄)ᵀ over the piece's points a..b−1.
  Eigen::Matrix2d scatter(std::size_t a, std::size_t b) const {
    const Eigen::Vector2d s = sum_[b] - sum_[a];
    return sum_sq_[b] - sum_sq_[a] - s * s.transpose() / static_cast<double>(b - a);
  }

 private:
  std::size_t first_;
  std::vector<Eigen::Vector2d> sum_;
  std::vector<Eigen::Matrix2d> sum_sq_;
  double sigma_ = 0;
};

// Where a piece that passes the straightness test is two parallel surfaces side by side (a door frame 8 cm proud of
// the wall, seen from the side: no range jump, and a line fitted to both lies within 4 cm of every point): the
// index k that best splits the piece into two runs of at least kMinSide points fitted by two parallel lines
// (one direction, two offsets), when their offsets differ by more than twice split_distance_m (and 4σ of that
// difference) and each side lies along the common direction. nullopt when there is no such step.
std::optional<std::size_t> step_at(const PieceSums& sums, const ScanLineOptions& options) {
  constexpr std::size_t kMinSide = 3;
  const std::size_t n = sums.size();
  if (n < 2 * kMinSide) return std::nullopt;
  std::optional<std::size_t> best;
  double best_excess = 1.0;
  for (std::size_t k = kMinSide; k + kMinSide <= n; ++k) {
    const double nl = static_cast<double>(k), nr = static_cast<double>(n - k);
    const Eigen::Matrix2d left = sums.scatter(0, k), right = sums.scatter(k, n);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(left + right);
    const Eigen::Vector2d across = eigen.eigenvectors().col(0);
    const double offset = std::abs(across.dot(sums.mean(0, k) - sums.mean(k, n)));
    const double threshold =
        std::max(2.0 * options.split_distance_m, 4.0 * sums.sigma() * std::sqrt(1.0 / nl + 1.0 / nr));
    // Each side must itself lie along the common direction (its own RMS spread across it under a quarter of the
    // offset): the two sides of a bend spread about it, and a bend is the split's business, not a step's.
    const double most_spread_sq = 0.0625 * offset * offset;
    if (offset / threshold > best_excess && across.dot(left * across) / nl < most_spread_sq &&
        across.dot(right * across) / nr < most_spread_sq) {
      best_excess = offset / threshold;
      best = sums.first() + k;
    }
  }
  return best;
}

// Where a piece that passes the straightness test is two lines meeting at a shallow bend (two facets of a curved
// wall 6–9° apart, a wall meeting another at a slight angle): one line fitted to both tilts to split the difference,
// so no point lies far from it, yet the shorter side runs off the longer side's line by more than split_distance_m
// at its far end. The index k (its point shared by both sides) where two lines of at least kMinSide points each fit
// the piece best, when their directions differ by more than 4σ of their difference and by enough that the shorter
// side's end lies split_distance_m off the longer side's line. nullopt when there is no such bend.
std::optional<std::size_t> bend_at(const std::vector<Eigen::Vector2d>& points, const PieceSums& sums,
                                   const ScanLineOptions& options) {
  constexpr std::size_t kMinSide = 5;
  const std::size_t n = sums.size();
  if (n < 2 * kMinSide) return std::nullopt;
  // The direction of a side's points and the spread along it (Σ (t − t̄)², the larger eigenvalue of its scatter).
  struct Side {
    Eigen::Vector2d direction;
    double spread_sq;
  };
  const auto side = [](const Eigen::Matrix2d& scatter) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(scatter);
    return Side{eigen.eigenvectors().col(1), eigen.eigenvalues()(1)};
  };
  // The smaller eigenvalue of a 2×2 scatter in closed form: the loop runs over every point of every straight piece.
  const auto residual_sq = [](const Eigen::Matrix2d& m) {
    const double half_trace = 0.5 * (m(0, 0) + m(1, 1)), half_diff = 0.5 * (m(0, 0) - m(1, 1));
    return std::max(0.0, half_trace - std::sqrt(half_diff * half_diff + m(0, 1) * m(0, 1)));
  };
  // The bend is where two lines fit best (least residual, the corner point on both sides); it is one when the sides'
  // directions differ by more than 4σ and the shorter side's far end runs split_distance_m off the longer's line.
  std::optional<std::size_t> best;
  double best_residual = std::numeric_limits<double>::infinity();
  for (std::size_t k = kMinSide - 1; k + kMinSide <= n; ++k) {
    const double residual = residual_sq(sums.scatter(0, k + 1)) + residual_sq(sums.scatter(k, n));
    if (residual < best_residual) {
      best_residual = residual;
      best = k;
    }
  }
  if (!best) return std::nullopt;
  const std::size_t k = *best;
  const Side best_left = side(sums.scatter(0, k + 1)), best_right = side(sums.scatter(k, n));
  if (best_left.spread_sq <= 0 || best_right.spread_sq <= 0) return std::nullopt;
  const double angle = std::acos(std::min(1.0, std::abs(best_left.direction.dot(best_right.direction))));
  // σ across the lines: the noise model's, or what the two sides' own residuals show when that is more (a scanner
  // noisier than its model must not see bends in a straight wall).
  const double scatter = std::sqrt(best_residual / (static_cast<double>(n) + 1.0 - 4.0));
  const double sigma_angle =
      std::max(sums.sigma(), scatter) * std::sqrt(1.0 / best_left.spread_sq + 1.0 / best_right.spread_sq);
  const std::size_t first = sums.first(), corner = first + k, last = first + n - 1;
  const double left_length = (points[corner] - points[first]).norm();
  const double right_length = (points[last] - points[corner]).norm();
  const double off_m = std::min(left_length, right_length) * std::sin(angle);
  if (angle <= 4.0 * sigma_angle || off_m <= options.split_distance_m) return std::nullopt;
  return corner;
}

// Where the step test, then the bend test, would split a straight piece: {index, whether it is a step}. A step's
// index starts the second side; a bend's index is the corner both sides share.
struct Cut {
  std::size_t index;
  bool step;
};
std::optional<Cut> straight_cut(const std::vector<Eigen::Vector2d>& points, const std::vector<Eigen::Matrix2d>& covs,
                                Piece piece, const Eigen::Vector2d& normal, const ScanLineOptions& options) {
  if (!options.split_steps && !options.split_bends) return std::nullopt;
  const PieceSums sums(points, covs, piece, normal);
  if (options.split_steps)
    if (const auto k = step_at(sums, options)) return Cut{*k, true};
  if (options.split_bends)
    if (const auto k = bend_at(points, sums, options)) return Cut{*k, false};
  return std::nullopt;
}

// Splits [first, last) while some point lies farther than the threshold from the piece's least-squares line,
// at the interior point farthest from the chord between the end points (the corner, for an L). Testing
// against the fitted line rather than the chord keeps long noisy walls whole: the chord is off by the
// noise of its two end points.
void split(const std::vector<Eigen::Vector2d>& points, const std::vector<Eigen::Matrix2d>& covs, Piece piece,
           const ScanLineOptions& options, std::vector<Piece>& out) {
  const std::size_t n = piece.last - piece.first;
  if (n < 3) {
    out.push_back(piece);
    return;
  }
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (std::size_t i = piece.first; i < piece.last; ++i) mean += points[i];
  mean /= static_cast<double>(n);
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (std::size_t i = piece.first; i < piece.last; ++i) scatter += (points[i] - mean) * (points[i] - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(scatter);
  const Eigen::Vector2d normal = eigen.eigenvectors().col(0);  // the direction of least spread
  bool straight = true;
  for (std::size_t i = piece.first; i < piece.last && straight; ++i) {
    // 4σ: with a few hundred points per wall, 3σ would cut a straight wall at random.
    straight = std::abs(normal.dot(points[i] - mean)) <=
               std::max(options.split_distance_m, 4.0 * normal_sigma(covs[i], normal));
  }
  if (straight) {
    if (const auto cut = straight_cut(points, covs, piece, normal, options)) {
      split(points, covs, {piece.first, cut->step ? cut->index : cut->index + 1}, options, out);
      split(points, covs, {cut->index, piece.last}, options, out);
      return;
    }
    out.push_back(piece);
    return;
  }
  const Eigen::Vector2d a = points[piece.first];
  const Eigen::Vector2d chord = points[piece.last - 1] - a;
  const double length = chord.norm();
  std::size_t corner = piece.first + n / 2;
  if (length > 1e-9) {
    const Eigen::Vector2d chord_normal(-chord.y() / length, chord.x() / length);
    double farthest = -1.0;
    for (std::size_t i = piece.first + 1; i + 1 < piece.last; ++i) {
      const double d = std::abs(chord_normal.dot(points[i] - a));
      if (d > farthest) {
        farthest = d;
        corner = i;
      }
    }
  }
  // The corner point belongs to both sides.
  split(points, covs, {piece.first, corner + 1}, options, out);
  split(points, covs, {corner, piece.last}, options, out);
}

struct LocalSegment {
  Piece piece;
  LineSegment segment;  // sensor frame
};

// Whether the end point `end` lies off the line the other points of the piece fit (by the split threshold): the
// corner point a split gives both sides, or the first points of the next wall, which would tilt a short segment.
bool end_is_off(const std::vector<Eigen::Vector2d>& points, const std::vector<Eigen::Matrix2d>& covs, Piece rest,
                std::size_t end, const ScanLineOptions& options) {
  const std::size_t n = rest.last - rest.first;
  try {
    const LineFeature line = fit_line(std::span<const Eigen::Vector2d>(points.data() + rest.first, n),
                                      std::span<const Eigen::Matrix2d>(covs.data() + rest.first, n));
    return std::abs(line.signed_distance(points[end])) >
           std::max(options.split_distance_m, 4.0 * normal_sigma(covs[end], line.normal()));
  } catch (const std::invalid_argument&) {
    return false;
  }
}

std::optional<LocalSegment> fit_piece(const std::vector<Eigen::Vector2d>& points,
                                      const std::vector<Eigen::Matrix2d>& covs, Piece piece,
                                      const ScanLineOptions& options) {
  // Trim end points that do not belong to the line of the others (at most a few at each end), down to four points:
  // min_points counts the piece as split, and a short piece that kept a corner point would come out tilted by
  // 10–15°. The line that judges an end leaves out the point next to it too, so two points of the next wall at one
  // end cannot pull it toward themselves.
  if (piece.last - piece.first < options.min_points) return std::nullopt;
  constexpr std::size_t kFewestFitted = 4;
  for (int trims = 0; trims < 4 && piece.last - piece.first > kFewestFitted; ++trims) {
    const std::size_t skip = piece.last - piece.first >= 6 ? 2 : 1;
    if (end_is_off(points, covs, {piece.first + skip, piece.last}, piece.first, options)) {
      ++piece.first;
    } else if (end_is_off(points, covs, {piece.first, piece.last - skip}, piece.last - 1, options)) {
      --piece.last;
    } else {
      break;
    }
  }
  const std::size_t n = piece.last - piece.first;
  const std::span<const Eigen::Vector2d> p(points.data() + piece.first, n);
  const std::span<const Eigen::Matrix2d> q(covs.data() + piece.first, n);
  LineFeature line;
  try {
    line = fit_line(p, q);
  } catch (const std::invalid_argument&) {
    return std::nullopt;  // degenerate (coincident points): not a line
  }
  if (options.scale_by_residuals && n > 2) {
    // A posteriori variance factor: residuals larger than the point noise explains (a wall that is not quite
    // straight, mixed pixels at an edge, the split tolerance) make the fit less certain than the noise model says.
    double chi2 = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double d = line.signed_distance(p[i]);
      chi2 += d * d / std::max(normal_sigma(q[i], line.normal()) * normal_sigma(q[i], line.normal()), 1e-12);
    }
    const double factor = chi2 / static_cast<double>(n - 2);
    if (factor > 1.0) line.cov *= factor;
  }
  LineSegment segment{line, line.coordinate_along(p.front()), line.coordinate_along(p.back())};
  if (segment.t0_m > segment.t1_m) std::swap(segment.t0_m, segment.t1_m);
  if (segment.length_m() < options.min_length_m) return std::nullopt;
  return LocalSegment{piece, segment};
}

// Whether every point of the piece lies within the split threshold of the line (the split's own test).
bool on_line(const std::vector<Eigen::Vector2d>& points, const std::vector<Eigen::Matrix2d>& covs, Piece piece,
             const LineFeature& line, const ScanLineOptions& options) {
  for (std::size_t i = piece.first; i < piece.last; ++i) {
    if (std::abs(line.signed_distance(points[i])) >
        std::max(options.split_distance_m, 4.0 * normal_sigma(covs[i], line.normal())))
      return false;
  }
  return true;
}

// Whether two returns `distance` apart could lie on one surface seen at an incidence of at least lambda: within the
// adaptive breakpoint distance (Borges & Aldon 2004) r_a·sin Δφ / sin(λ − Δφ) + 3σ_r, the spacing of two returns
// from a surface seen at incidence λ, plus the range noise.
bool within_adaptive_distance(const RangeReading& a, const RangeReading& b, double distance, double lambda,
                              const ScanLineOptions& options) {
  const double dphi = std::abs(b.bearing_rad - a.bearing_rad);
  if (dphi >= lambda) return false;
  const double sigma_r = options.sigma_range_m + options.sigma_range_relative * std::max(a.range_m, b.range_m);
  return distance <= a.range_m * std::sin(dphi) / std::sin(lambda - dphi) + 3.0 * sigma_r;
}

// Whether a gap always cuts a run: wider than max_gap_m, unless a far wall's returns may lie farther apart than
// max_gap_m and still be one surface, when the spacing is what a surface seen at far_gap_lambda_rad or steeper gives
// from that range.
bool cuts_as_gap(const RangeReading& a, const RangeReading& b, double distance, const ScanLineOptions& options) {
  if (distance <= options.max_gap_m) return false;
  if (options.far_gap_lambda_rad <= 0 || std::max(a.range_m, b.range_m) > options.far_gap_max_range_m ||
      distance > options.far_gap_max_m)
    return true;
  if (options.bearing_step_rad > 0 && std::abs(b.bearing_rad - a.bearing_rad) / options.bearing_step_rad >
                                          static_cast<double>(options.max_missing_beams) + 1.5)
    return true;
  return !within_adaptive_distance(a, b, distance, options.far_gap_lambda_rad, options);
}

// Whether consecutive readings a, b (points pa, pb in the sensor frame) may belong to different runs: farther apart
// than max_gap_m, or than the adaptive breakpoint distance (Borges & Aldon 2004) r_a·sin Δφ / sin(λ − Δφ) + 3σ_r — the
// spacing of two returns from a surface seen at incidence λ, plus the range noise.
bool breaks_between(const RangeReading& a, const RangeReading& b, const Eigen::Vector2d& pa, const Eigen::Vector2d& pb,
                    const ScanLineOptions& options) {
  const double distance = (pb - pa).norm();
  if (distance > options.max_gap_m) return true;
  if (!options.adaptive_breakpoints) return false;
  return !within_adaptive_distance(a, b, distance, options.breakpoint_lambda_rad, options);
}

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("extract_scan_lines: " + what);
}

}  // namespace

std::vector<LineSegment> extract_scan_lines(const std::vector<RangeReading>& readings, const Pose2D& sensor_pose,
                                            const Eigen::Matrix3d& pose_cov, const ScanLineOptions& options) {
  require(options.min_points >= 2, "min_points must be >= 2");
  require(std::isfinite(options.min_length_m) && options.min_length_m >= 0, "min_length_m must be finite and >= 0");
  require(std::isfinite(options.max_gap_m) && options.max_gap_m > 0, "max_gap_m must be finite and > 0");
  require(std::isfinite(options.split_distance_m) && options.split_distance_m > 0, "split_distance_m must be > 0");
  require(std::isfinite(options.merge_chi2) && options.merge_chi2 >= 0, "merge_chi2 must be finite and >= 0");
  require(options.sigma_range_m > 0 && std::isfinite(options.sigma_range_m), "sigma_range_m must be > 0");
  require(options.sigma_range_relative >= 0 && options.sigma_bearing_rad >= 0, "noise terms must be >= 0");
  require(options.far_gap_lambda_rad >= 0 && options.far_gap_lambda_rad < std::numbers::pi / 2,
          "far_gap_lambda_rad must be in [0, pi/2)");
  require(std::isfinite(options.far_gap_max_m) && options.far_gap_max_m >= 0, "far_gap_max_m must be finite and >= 0");
  require(std::isfinite(options.far_gap_max_range_m) && options.far_gap_max_range_m >= 0,
          "far_gap_max_range_m must be finite and >= 0");
  require(std::isfinite(options.bearing_step_rad) && options.bearing_step_rad >= 0,
          "bearing_step_rad must be finite and >= 0");
  require(options.breakpoint_lambda_rad > 0 && options.breakpoint_lambda_rad < std::numbers::pi / 2,
          "breakpoint_lambda_rad must be in (0, pi/2)");
  require(std::isfinite(options.breakpoint_isolation) && options.breakpoint_isolation >= 0,
          "breakpoint_isolation must be finite and >= 0");
  require(std::isfinite(sensor_pose.x_m) && std::isfinite(sensor_pose.y_m) && std::isfinite(sensor_pose.theta_rad),
          "sensor pose is not finite");
  require(pose_cov.allFinite(), "pose_cov is not finite");

  // Points and their covariance in the sensor frame: Q = J diag(σr², σθ²) Jᵀ, J = ∂(x, y)/∂(r, θ).
  std::vector<Eigen::Vector2d> points;
  std::vector<Eigen::Matrix2d> covs;
  points.reserve(readings.size());
  covs.reserve(readings.size());
  for (const auto& r : readings) {
    require(std::isfinite(r.range_m) && r.range_m > 0 && std::isfinite(r.bearing_rad),
            "a reading is not finite and > 0");
    const double c = std::cos(r.bearing_rad), s = std::sin(r.bearing_rad);
    const double sigma_r = options.sigma_range_m + options.sigma_range_relative * r.range_m;
    // The bearing noise must not vanish entirely: a zero-variance direction makes Q singular.
    const double sigma_b = std::max(options.sigma_bearing_rad, 1e-6);
    Eigen::Matrix2d j;
    j << c, -r.range_m * s, s, r.range_m * c;
    const Eigen::Vector2d variances(sigma_r * sigma_r, sigma_b * sigma_b);
    points.emplace_back(r.range_m * c, r.range_m * s);
    covs.push_back(j * variances.asDiagonal() * j.transpose());
  }

  // Runs of points without gaps or breakpoints, then split. run_of[i] numbers the run of point i: pieces of two runs
  // are never merged.
  std::vector<Piece> pieces;
  std::vector<std::size_t> run_of(points.size(), 0);
  std::size_t run_start = 0;
  const auto spacing = [&points](std::size_t i) {  // between points i − 1 and i; 0 outside the scan
    return i >= 1 && i < points.size() ? (points[i] - points[i - 1]).norm() : 0.0;
  };
  const auto isolated = [&](std::size_t i) {
    return options.breakpoint_isolation <= 0 ||
           spacing(i) > options.breakpoint_isolation * std::max(spacing(i - 1), spacing(i + 1));
  };
  for (std::size_t i = 1; i <= points.size(); ++i) {
    if (i == points.size() ||
        (cuts_as_gap(readings[i - 1], readings[i], (points[i] - points[i - 1]).norm(), options) ||
         (breaks_between(readings[i - 1], readings[i], points[i - 1], points[i], options) && isolated(i)))) {
      if (i > run_start) split(points, covs, {run_start, i}, options, pieces);
      run_start = i;
    }
    if (i < points.size()) run_of[i] = run_of[i - 1] + (run_start == i ? 1 : 0);
  }

  std::vector<LocalSegment> segments;
  for (const auto& piece : pieces)
    if (auto fitted = fit_piece(points, covs, piece, options)) segments.push_back(*fitted);

  // Merge neighbours in scan order whose lines agree and that touch; refit over the union. Only within a run (a
  // breakpoint is a depth step), and only when every point of the union, including those between the two pieces,
  // lies on the refitted line by the split's test: a pilaster or a recess between two collinear pieces of a wall
  // may have given no segment of its own (too short), and the refit would otherwise take its points in and come
  // out tilted or shifted toward it.
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t k = 0; k + 1 < segments.size(); ++k) {
      const auto& a = segments[k];
      const auto& b = segments[k + 1];
      if (run_of[a.piece.first] != run_of[b.piece.last - 1]) continue;
      const double gap = (points[b.piece.first] - points[a.piece.last - 1]).norm();
      if (cuts_as_gap(readings[a.piece.last - 1], readings[b.piece.first], gap, options)) continue;
      if (mahalanobis_squared(a.segment.line, b.segment.line) > options.merge_chi2) continue;
      const Piece joined{a.piece.first, std::max(a.piece.last, b.piece.last)};
      auto refit = fit_piece(points, covs, joined, options);
      if (!refit || !on_line(points, covs, refit->piece, refit->segment.line, options)) continue;
      // Two faces the step test split apart, or two facets the bend test did, stay apart however well their lines
      // agree.
      if (straight_cut(points, covs, refit->piece, refit->segment.line.normal(), options)) continue;
      segments[k] = *refit;
      segments.erase(segments.begin() + static_cast<std::ptrdiff_t>(k + 1));
      merged = true;
      break;
    }
  }

  // Into the world frame.
  std::vector<LineSegment> world;
  world.reserve(segments.size());
  for (const auto& local : segments) world.push_back(transform_segment(local.segment, sensor_pose, pose_cov));
  return world;
}

}  // namespace wm::fusion
