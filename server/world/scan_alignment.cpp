#include "server/world/scan_alignment.h"

#include <algorithm>
#include <cmath>

namespace wm::world {

fusion::ScanAlignment align_to_map(const WorldState& state, const std::vector<fusion::LineSegment>& local,
                                   const fusion::Pose2D& posted_pose, const Eigen::Matrix3d& posted_cov,
                                   const WorldOptions& world_options, const fusion::ScanAlignmentOptions& options) {
  // Within reach: the farthest line end, plus as far as the alignment looks around it (a pose posted as a guess
  // is not aligned; its σ, capped, bounds what is gathered).
  double range_m = 0;
  for (const auto& segment : local) range_m = std::max({range_m, segment.p0().norm(), segment.p1().norm()});
  const double sigma_xy = std::min(std::sqrt(std::max(posted_cov(0, 0), posted_cov(1, 1))), options.max_posted_sigma_m);
  const double sigma_theta = std::min(std::sqrt(std::max(posted_cov(2, 2), 0.0)), options.max_posted_sigma_rad);
  const double reach_m = range_m + fusion::alignment_reach_m(sigma_xy, sigma_theta, range_m);
  const Box near{posted_pose.x_m - reach_m, posted_pose.y_m - reach_m, posted_pose.x_m + reach_m,
                 posted_pose.y_m + reach_m};

  std::vector<fusion::AlignmentReference> references;
  for (const auto& [i, k] : state.objects.edges_near(near)) {
    if (!state.objects[i].plan->has_attribute("solid")) continue;
    auto edge = apriori_edge(state.objects[i], k, world_options);
    if (Box::of(edge).overlaps(near)) references.push_back({std::move(edge), std::nullopt});
  }
  for (const auto number : state.elements.near(near)) {
    const Element& element = state.elements.at(number);
    if (element.origin == "grid" || !Box::of(element.segment).overlaps(near)) continue;
    references.push_back({element.segment, element.facing_rad});
  }
  return fusion::align_scan_lines(local, posted_pose, posted_cov, references, options);
}

}  // namespace wm::world
