#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "fusion/grid/scan.h"

namespace wm::logs {

/// A laser scan as the body of POST /api/v1/scans (sensor, source, stamp, pose, beams, ranges with null for a
/// reading that is not finite, range limits, sigma_range), without pose_cov and the optional fields, which
/// callers add when they have them.
nlohmann::json laser_scan_body(const fusion::LaserScan& scan, const std::string& source, double stamp);

}  // namespace wm::logs
