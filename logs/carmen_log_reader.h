#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "fusion/grid/scan.h"

namespace wm::logs {

/// A malformed line of a known type, an unreadable file or a corrupt gzip stream. what() is "file:line: reason".
class LogError : public std::runtime_error {
 public:
  LogError(const std::filesystem::path& file, std::size_t line, const std::string& reason);
  const std::filesystem::path& file() const { return file_; }
  /// 1-based line number; 0 when the error is not about a line (opening the file).
  std::size_t line() const { return line_; }

 private:
  std::filesystem::path file_;
  std::size_t line_;
};

/// One laser scan of a log, with where it came from.
struct LogScan {
  std::size_t line_number = 0;  // 1-based
  double timestamp_s = 0.0;     // the message's ipc_timestamp [s]; not monotonic in real logs, so replay in line order
  fusion::LaserScan scan;       // sensor pose in the log's world frame
};

/// What a CARMEN log does not say about its laser.
struct CarmenReaderOptions {
  /// FLASER carries no maximum range: a reading >= this is "no return" [m]. 50 m covers the "no return" codes of
  /// the 13 corrected CARMEN logs we test with (81.83–81.91 m, 50–51.25 m); orebro-corrected writes 32.767 m and
  /// needs 32.7.
  /// ROBOTLASER1 lines carry their own maximum_range and ignore this.
  double flaser_range_max_m = 50.0;
  double range_min_m = 0.02;    // readings below are ignored [m]
  double sigma_range_m = 0.01;  // range standard deviation given to every scan [m] (SICK LMS, docs/fusion.md §5)
};

/// Reads a CARMEN log, plain or gzip-compressed (detected from the content), line by line in file order, and
/// returns its laser scans:
///  - FLASER (old format): `FLASER n r_1..r_n x y theta odom_x odom_y odom_theta ipc_timestamp host
///    logger_timestamp`. The pose is the (corrected) robot pose x y theta; the laser sits
///    `PARAM robot_frontlaser_offset` metres ahead of it along theta (0 until such a PARAM line is read).
///    Beam angles are inferred from n over a 180° fan: even n (180, 360) steps of π/n from −90°, odd n (181, 361)
///    steps of π/(n − 1) from −90° to +90°.
///  - ROBOTLASER1 (new format): `ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode n
///    r_1..r_n m e_1..e_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv fsd ssd turn_axis
///    ipc_timestamp host logger_timestamp`, using the laser pose, start_angle + i·resolution and max_range as
///    the "no return" threshold.
/// Other lines (ODOM, NEFF, other PARAMs, comments, blank lines) are skipped.
class CarmenLogReader {
 public:
  /// @throw LogError (line 0) when the file cannot be opened.
  explicit CarmenLogReader(const std::filesystem::path& path, const CarmenReaderOptions& options = {});
  ~CarmenLogReader();
  CarmenLogReader(CarmenLogReader&&) noexcept;
  CarmenLogReader& operator=(CarmenLogReader&&) noexcept;
  CarmenLogReader(const CarmenLogReader&) = delete;
  CarmenLogReader& operator=(const CarmenLogReader&) = delete;

  /// The next scan in file order, or nullopt at the end of the file.
  /// @throw LogError for a FLASER / ROBOTLASER1 / robot_frontlaser_offset line with a wrong field count, a field
  ///        that is not a number, a non-finite pose, or an impossible header (n < 2, max_range <= 0), and for a
  ///        read error or a corrupt or truncated gzip stream.
  std::optional<LogScan> next();
  /// Lines consumed so far (the number of the last line read).
  std::size_t lines_read() const;
  /// Lines consumed so far that produced no scan.
  std::size_t skipped_lines() const;
  /// Fraction of the file consumed, by (compressed) bytes, in [0, 1].
  double progress() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wm::logs
