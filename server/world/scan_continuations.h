#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "fusion/geometry/line.h"
#include "fusion/lines/line_continuation.h"
#include "server/world/world_state.h"

namespace wm::world {

/// How far an element's line runs past one of its ends, as one scan shows it (world frame).
struct ScanContinuation {
  std::int64_t element = 0;
  fusion::LineSegment segment;  // on the element's line, from its end on; the pose's covariance propagated
};

/// The continuations one scan gives of the map's elements, from returns too sparse for the scan-line extractor
/// (fusion::continue_line at both ends of every element within the sensor's range whose seen side faces the
/// sensor). A return within 3 cm of another element's line, within its extent and 10 cm beyond, is that element's:
/// an element's continuation stops at it. Elements the grid extractor made are neither continued nor stop others:
/// their lines are known only to their cells. `beams` are in the sensor's frame; `pose` places the sensor,
/// `pose_cov` is propagated into each segment.
std::vector<ScanContinuation> scan_continuations(const WorldState& state,
                                                 std::span<const fusion::ContinuationBeam> beams,
                                                 const fusion::Pose2D& pose, const Eigen::Matrix3d& pose_cov,
                                                 const fusion::LineContinuationOptions& options);

}  // namespace wm::world
