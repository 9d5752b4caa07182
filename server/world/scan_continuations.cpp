#include "server/world/scan_continuations.h"

#include <cmath>

#include "server/world/update_internal.h"

namespace wm::world {
namespace {

constexpr double kOnLineM = 0.03;   // a return this close to an element's line lies on it...
constexpr double kPastEndM = 0.10;  // ...within its extent and this far beyond
constexpr std::int64_t kNone = -1, kSeveral = -2;

}  // namespace

std::vector<ScanContinuation> scan_continuations(const WorldState& state,
                                                 std::span<const fusion::ContinuationBeam> beams,
                                                 const fusion::Pose2D& pose, const Eigen::Matrix3d& pose_cov,
                                                 const fusion::LineContinuationOptions& options) {
  std::vector<ScanContinuation> continuations;
  const double reach = options.max_range_m;
  const Box near{pose.x_m - reach, pose.y_m - reach, pose.x_m + reach, pose.y_m + reach};
  const Eigen::Vector2d sensor(pose.x_m, pose.y_m);
  const double grazing_reach = options.max_range_m * std::sin(options.max_incidence_rad), range_sq = reach * reach;
  // Which element a return lies on (kSeveral: more than one), worked out for the returns a continuation reaches.
  constexpr std::int64_t kNotAsked = -3;
  std::vector<std::int64_t> owner(beams.size(), kNotAsked);
  const auto owner_of = [&](std::size_t b) {
    if (owner[b] != kNotAsked) return owner[b];
    owner[b] = kNone;
    const Eigen::Vector2d p = pose.transform_point(beams[b].range_m * beams[b].direction);
    for (const auto number : state.elements.near(Box{p.x(), p.y(), p.x(), p.y()})) {
      const Element& element = state.elements.at(number);
      if (update_internal::made_by_grid(element) || std::abs(element.segment.line.signed_distance(p)) > kOnLineM)
        continue;
      const double t = element.segment.line.coordinate_along(p);
      if (t < element.segment.t0_m - kPastEndM || t > element.segment.t1_m + kPastEndM) continue;
      owner[b] = owner[b] == kNone ? number : kSeveral;
    }
    return owner[b];
  };
  for (const auto number : state.elements.near(near)) {
    const Element& element = state.elements.at(number);
    const auto& segment = element.segment;
    // Only a line within max_range · sin(max_incidence) of the sensor is ever grazed within range, and only past an
    // end within range.
    if (update_internal::made_by_grid(element) || !Box::of(segment).overlaps(near) ||
        ((segment.p0() - sensor).squaredNorm() >= range_sq && (segment.p1() - sensor).squaredNorm() >= range_sq) ||
        std::abs(segment.line.signed_distance(sensor)) > grazing_reach)
      continue;
    // The face the element was seen from must face the sensor: the other face of a wall is another surface.
    if (element.facing_rad && !element.both_ways &&
        Eigen::Vector2d(std::cos(*element.facing_rad), std::sin(*element.facing_rad)).dot(sensor - segment.p0()) <= 0)
      continue;
    const auto local = fusion::LineSegment::from_points(pose.inverse_transform_point(segment.p0()),
                                                        pose.inverse_transform_point(segment.p1()),
                                                        Eigen::Matrix2d::Identity() * 1e-8);
    const fusion::ForeignReturn foreign = [&](std::size_t b) {
      const auto o = owner_of(b);
      return o != kNone && o != number;
    };
    for (const bool beyond_t1 : {false, true}) {
      if (auto view = fusion::continue_line(beams, local, beyond_t1, options, foreign)) {
        // Back in the world frame the view lies on the element's line; the pose's uncertainty is its own.
        continuations.push_back({number, fusion::transform_segment(*view, pose, pose_cov)});
      }
    }
  }
  return continuations;
}

}  // namespace wm::world
