#pragma once

// The scan journal's binary form of a scan: what start-up replays into the grid, without the wire format it came in.
#include <string>
#include <string_view>

#include "server/world/scan_observation.h"

namespace wm::storage {

/// Largest number of readings a stored scan may carry (a bound for a damaged row, far above any real sensor).
inline constexpr std::size_t kMaxStoredReadings = 1u << 20;

/// The scan without its observer and stamp (columns of their own), little-endian:
///   "WMS1", kind (u8: 1 laser, 2 sonar), the sensor pose (x, y, θ) and its covariance (9 f64, row-major), then
///   laser: angle_min, angle_increment, range_min, range_max, σ, σ per metre, usable range (f64), n (u32), n ranges;
///   sonar: beam width, range_min, range_max, σ (f64), n (u32), n angles, n ranges.
/// Doubles are kept bit for bit, so a replay puts into the grid exactly what the first run did.
std::string encode_scan(const world::ScanObservation& scan);
/// The scan `blob` holds, with `observer` and `stamp_s` from its row.
/// @throw StorageError naming what is wrong (magic, kind, size, a count over kMaxStoredReadings, a scan that fails
/// fusion::validate), never anything else.
world::ScanObservation decode_scan(std::string_view blob, std::string observer, double stamp_s);

}  // namespace wm::storage
