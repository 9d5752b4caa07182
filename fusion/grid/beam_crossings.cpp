#include "fusion/grid/beam_crossings.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace wm::fusion {
namespace {

void bump(std::uint32_t& count) {
  if (count != std::numeric_limits<std::uint32_t>::max()) ++count;
}

}  // namespace

std::size_t beam_bins(double length_m, const BeamCrossingOptions& options) {
  return std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(length_m / options.bin_m - 1e-9)));
}

void count_beam_crossings(const LaserScan& scan, double reach_m, const BeamCrossingOptions& options,
                          std::vector<SegmentBeams>& segments, const Eigen::Matrix3d& pose_cov) {
  if (!(options.bin_m > 0) || !(options.margin_m > 0) || !(options.min_incidence_rad >= 0) ||
      !(options.min_incidence_rad < std::numbers::pi / 2) || !std::isfinite(options.bin_m) ||
      !std::isfinite(options.margin_m))
    throw std::invalid_argument("count_beam_crossings: bad options");
  if (!std::isfinite(reach_m) || reach_m < 0) throw std::invalid_argument("count_beam_crossings: bad reach");
  if (!pose_cov.allFinite() || pose_cov(0, 0) < 0 || pose_cov(1, 1) < 0 || pose_cov(2, 2) < 0)
    throw std::invalid_argument("count_beam_crossings: bad pose covariance");
  validate(scan);  // a non-finite pose or angle would index beams out of range
  const std::size_t beams = scan.ranges_m.size();
  if (beams == 0 || scan.angle_increment_rad == 0) return;
  const Eigen::Vector2d origin(scan.sensor_pose.x_m, scan.sensor_pose.y_m);
  const double first = scan.sensor_pose.theta_rad + scan.angle_min_rad;
  const double step = scan.angle_increment_rad;
  const double sin_min = std::sin(options.min_incidence_rad);
  for (auto& segment : segments) {
    const Eigen::Vector2d a = segment.p0 - origin, b = segment.p1 - origin;
    const Eigen::Vector2d along = segment.p1 - segment.p0;
    const double length = along.norm();
    const std::size_t bins = beam_bins(length, options);
    if (segment.through.size() != bins || segment.ended.size() != bins)
      throw std::invalid_argument("count_beam_crossings: a segment's bins do not match its length");
    if (length <= 0) continue;
    const Eigen::Vector2d normal = Eigen::Vector2d(-along.y(), along.x()) / length;
    const double position_var = std::max(0.0, normal.dot(pose_cov.topLeftCorner<2, 2>() * normal));
    // The beams whose bearing lies between the ends' (the shorter way round: a segment never subtends π or more
    // unless the sensor is on it, and then no beam crosses it at an angle).
    const double angle_a = std::atan2(a.y(), a.x()), angle_b = std::atan2(b.y(), b.x());
    const double span = std::remainder(angle_b - angle_a, 2 * std::numbers::pi);
    const double from = span >= 0 ? angle_a : angle_b;
    const double width = std::abs(span);
    // Out of reach: no beam saw it.
    const double nearest_u = std::clamp(-a.dot(along) / (length * length), 0.0, 1.0);
    if ((a + nearest_u * along).norm() > reach_m + options.margin_m) continue;
    // Beam i's bearing relative to `from`, wrapped to [0, 2π): the indices in [from, from + width].
    const double offset = std::remainder(from - first, 2 * std::numbers::pi);
    const double direction = step > 0 ? 1.0 : -1.0;
    double i_start = offset / step, i_end = (offset + direction * width) / step;
    if (i_start > i_end) std::swap(i_start, i_end);
    // The scan may wrap: try the range and its copies one turn away.
    const double per_turn = 2 * std::numbers::pi / std::abs(step);
    for (const double turn : {-per_turn, 0.0, per_turn}) {
      const auto lo = static_cast<std::int64_t>(std::ceil(i_start + turn));
      const auto hi = static_cast<std::int64_t>(std::floor(i_end + turn));
      for (std::int64_t i = std::max<std::int64_t>(lo, 0); i <= hi && i < static_cast<std::int64_t>(beams); ++i) {
        const double bearing = first + static_cast<double>(i) * step;
        const Eigen::Vector2d dir(std::cos(bearing), std::sin(bearing));
        // Ray origin + t·dir against a + u·along: t along the beam, u in [0, 1] along the segment.
        const double denom = dir.x() * along.y() - dir.y() * along.x();
        if (std::abs(denom) < sin_min * length) continue;  // grazing (|sin| of the incidence below the minimum)
        const double t = (a.x() * along.y() - a.y() * along.x()) / denom;
        const double u = (a.x() * dir.y() - a.y() * dir.x()) / denom;
        if (t <= 0 || u < 0 || u > 1) continue;
        const double r = scan.ranges_m[static_cast<std::size_t>(i)];
        if (!std::isfinite(r) && !(r > 0)) continue;  // NaN: no reading
        if (std::isfinite(r) && (r < scan.range_min_m || r < 0)) continue;
        const bool returned = std::isfinite(r) && r < scan.range_max_m;
        const double seen_to = returned ? std::min(r, reach_m) : std::min(scan.range_max_m, reach_m);
        const auto bin = std::min(bins - 1, static_cast<std::size_t>(u * length / options.bin_m));
        // Judged across the segment, not along the beam: a return 10 cm from a wall along a beam at 15° is 2.6 cm
        // from it. The margin widens by two σ of where the pose and the reading put the return across the segment
        // (a heading error moves it by the range times the error, mostly across a wall it grazes).
        const double sin_incidence = std::abs(denom) / length;
        const double cos_incidence = std::sqrt(std::max(0.0, 1 - sin_incidence * sin_incidence));
        const double sigma_range = scan.sigma_range_m + scan.sigma_range_per_m * t;
        const double spread = std::sqrt(position_var + pose_cov(2, 2) * (t * cos_incidence) * (t * cos_incidence) +
                                        sigma_range * sigma_range * sin_incidence * sin_incidence);
        const double margin = options.margin_m + 2 * spread;
        if (returned && r <= reach_m && std::abs(r - t) * sin_incidence <= margin) {
          bump(segment.ended[bin]);
        } else if ((seen_to - t) * sin_incidence > margin) {
          bump(segment.through[bin]);
        }
      }
    }
  }
}

}  // namespace wm::fusion
