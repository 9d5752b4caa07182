#pragma once

#include <Eigen/Core>
#include <vector>

#include "fusion/geometry/line.h"
#include "fusion/registration/scan_alignment.h"
#include "server/world/world_state.h"

namespace wm::world {

/// Where one scan's lines put its sensor against the map: aligned to the elements that scans or clients made (a
/// grid line knows its wall only to its cells) and to the edges of the plan's `solid` objects (a not-deformable
/// object may have moved), each with its covariance, within reach of the scan. `local` are the scan's lines in the
/// sensor's own frame; see fusion::align_scan_lines.
fusion::ScanAlignment align_to_map(const WorldState& state, const std::vector<fusion::LineSegment>& local,
                                   const fusion::Pose2D& posted_pose, const Eigen::Matrix3d& posted_cov,
                                   const WorldOptions& world_options, const fusion::ScanAlignmentOptions& options);

}  // namespace wm::world
