#include "logs/carmen_log_reader.h"

#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>
#include <string_view>
#include <system_error>
#include <vector>

namespace wm::logs {
namespace {

constexpr std::size_t kChunk = 1 << 16;
constexpr std::size_t kMaxReadings = 100'000;  // far beyond any laser; guards the field-count arithmetic

struct GzClose {
  void operator()(gzFile f) const { gzclose(f); }
};

}  // namespace

LogError::LogError(const std::filesystem::path& file, std::size_t line, const std::string& reason)
    : std::runtime_error(file.string() + ":" + std::to_string(line) + ": " + reason), file_(file), line_(line) {}

struct CarmenLogReader::Impl {
  std::filesystem::path path;
  CarmenReaderOptions options;
  std::unique_ptr<gzFile_s, GzClose> file;
  std::uintmax_t file_size = 0;
  std::string buffer;  // bytes read but not yet consumed
  std::size_t buffer_pos = 0;
  bool eof = false;
  std::size_t lines = 0;
  std::size_t skipped = 0;
  double front_laser_offset_m = 0.0;
  std::vector<std::string_view> tokens;  // reused: no allocation per line

  [[noreturn]] void fail(const std::string& reason) const { throw LogError(path, lines, reason); }

  // Next line without its terminator (also a last line without one); false at the end of the file.
  bool read_line(std::string_view& line) {
    for (;;) {
      const std::size_t nl = buffer.find('\n', buffer_pos);
      if (nl != std::string::npos) {
        line = std::string_view(buffer).substr(buffer_pos, nl - buffer_pos);
        buffer_pos = nl + 1;
        return true;
      }
      if (eof) {
        if (buffer_pos >= buffer.size()) return false;
        line = std::string_view(buffer).substr(buffer_pos);
        buffer_pos = buffer.size();
        return true;
      }
      buffer.erase(0, buffer_pos);
      buffer_pos = 0;
      const std::size_t old = buffer.size();
      buffer.resize(old + kChunk);
      const int n = gzread(file.get(), buffer.data() + old, static_cast<unsigned>(kChunk));
      if (n < 0) {
        int code = 0;
        const char* msg = gzerror(file.get(), &code);
        ++lines;  // the error is about the line being read
        fail(std::string("read error: ") + (msg != nullptr ? msg : "unknown"));
      }
      buffer.resize(old + static_cast<std::size_t>(n));
      if (n == 0) {
        int code = 0;
        const char* msg = gzerror(file.get(), &code);
        // gzread reports a truncated stream only through gzerror.
        if (code != Z_OK && code != Z_STREAM_END) {
          ++lines;
          fail(std::string("corrupt or truncated gzip stream: ") + (msg != nullptr ? msg : "unknown"));
        }
        eof = true;
      }
    }
  }

  void split(std::string_view line) {
    tokens.clear();
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
      const std::size_t start = i;
      while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
      if (i > start) tokens.push_back(line.substr(start, i - start));
    }
  }

  double number(std::size_t index, const char* field) const {
    const std::string_view t = tokens[index];
    double v = 0.0;
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size()) {
      fail(std::string(field) + " is not a number: '" + std::string(t) + "'");
    }
    return v;
  }

  std::size_t count(std::size_t index, const char* field) const {
    const std::string_view t = tokens[index];
    std::size_t v = 0;
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size() || v > kMaxReadings) {
      fail(std::string(field) + " is not a count in [0, 100000]: '" + std::string(t) + "'");
    }
    return v;
  }

  void need_fields(std::size_t expected, const char* type) const {
    if (tokens.size() != expected) {
      fail(std::string(type) + " has " + std::to_string(tokens.size()) + " fields, expected " +
           std::to_string(expected));
    }
  }

  fusion::Pose2D pose(std::size_t index, const char* type) const {
    const fusion::Pose2D p{number(index, "x"), number(index + 1, "y"), number(index + 2, "theta")};
    if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.theta_rad)) {
      fail(std::string(type) + " pose is not finite");
    }
    return p;
  }

  void read_ranges(std::size_t first, std::size_t n, fusion::LaserScan& scan) const {
    scan.ranges_m.resize(n);
    for (std::size_t i = 0; i < n; ++i) scan.ranges_m[i] = number(first + i, "range");
  }

  LogScan parse_flaser() {
    if (tokens.size() < 2) fail("FLASER without a reading count");
    const std::size_t n = count(1, "FLASER num_readings");
    need_fields(n + 11, "FLASER");
    if (n < 2) fail("FLASER needs at least 2 readings to infer beam angles");
    LogScan out;
    out.line_number = lines;
    fusion::LaserScan& scan = out.scan;
    read_ranges(2, n, scan);
    const fusion::Pose2D robot = pose(2 + n, "FLASER");
    out.timestamp_s = number(2 + n + 6, "ipc_timestamp");
    scan.sensor_pose = {robot.x_m + front_laser_offset_m * std::cos(robot.theta_rad),
                        robot.y_m + front_laser_offset_m * std::sin(robot.theta_rad), robot.theta_rad};
    // A 180° fan: 180/360 beams start at −90° and stop one step short of +90°, 181/361 cover both ends.
    const double steps = (n % 2 == 0) ? static_cast<double>(n) : static_cast<double>(n - 1);
    scan.angle_min_rad = -std::numbers::pi / 2;
    scan.angle_increment_rad = std::numbers::pi / steps;
    scan.range_min_m = options.range_min_m;
    scan.range_max_m = options.flaser_range_max_m;
    scan.sigma_range_m = options.sigma_range_m;
    return out;
  }

  LogScan parse_robotlaser1() {
    if (tokens.size() < 9) fail("ROBOTLASER1 is too short for its header");
    const std::size_t n = count(8, "ROBOTLASER1 num_readings");
    if (tokens.size() < 10 + n) fail("ROBOTLASER1 is too short for its " + std::to_string(n) + " readings");
    const std::size_t m = count(9 + n, "ROBOTLASER1 num_remissions");
    need_fields(24 + n + m, "ROBOTLASER1");
    if (n < 1) fail("ROBOTLASER1 has no readings");
    LogScan out;
    out.line_number = lines;
    fusion::LaserScan& scan = out.scan;
    scan.angle_min_rad = number(2, "start_angle");
    scan.angle_increment_rad = number(4, "angular_resolution");
    scan.range_max_m = number(5, "maximum_range");
    if (!std::isfinite(scan.angle_min_rad) || !std::isfinite(scan.angle_increment_rad)) {
      fail("ROBOTLASER1 angles are not finite");
    }
    if (!(scan.range_max_m > options.range_min_m) || !std::isfinite(scan.range_max_m)) {
      fail("ROBOTLASER1 maximum_range must be finite and above range_min");
    }
    read_ranges(9, n, scan);
    const std::size_t after = 10 + n + m;
    scan.sensor_pose = pose(after, "ROBOTLASER1 laser");  // already includes the laser's mounting offset
    pose(after + 3, "ROBOTLASER1 robot");                 // checked, not used
    out.timestamp_s = number(after + 11, "ipc_timestamp");
    scan.range_min_m = options.range_min_m;
    scan.sigma_range_m = options.sigma_range_m;
    return out;
  }

  void parse_param() {
    if (tokens.size() >= 3 && tokens[1] == "robot_frontlaser_offset") {
      front_laser_offset_m = number(2, "robot_frontlaser_offset");
      if (!std::isfinite(front_laser_offset_m)) fail("robot_frontlaser_offset is not finite");
    }
  }
};

CarmenLogReader::CarmenLogReader(const std::filesystem::path& path, const CarmenReaderOptions& options)
    : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->options = options;
  std::error_code ec;
  impl_->file_size = std::filesystem::file_size(path, ec);
  if (ec) throw LogError(path, 0, "cannot open: " + ec.message());
  impl_->file.reset(gzopen(path.c_str(), "rb"));
  if (!impl_->file) throw LogError(path, 0, "cannot open");
  gzbuffer(impl_->file.get(), 1 << 17);
}

CarmenLogReader::~CarmenLogReader() = default;
CarmenLogReader::CarmenLogReader(CarmenLogReader&&) noexcept = default;
CarmenLogReader& CarmenLogReader::operator=(CarmenLogReader&&) noexcept = default;

std::optional<LogScan> CarmenLogReader::next() {
  Impl& r = *impl_;
  std::string_view line;
  while (r.read_line(line)) {
    ++r.lines;
    r.split(line);
    if (!r.tokens.empty()) {
      const std::string_view type = r.tokens[0];
      if (type == "FLASER") return r.parse_flaser();
      if (type == "ROBOTLASER1") return r.parse_robotlaser1();
      if (type == "PARAM") r.parse_param();
    }
    ++r.skipped;
  }
  return std::nullopt;
}

std::size_t CarmenLogReader::lines_read() const { return impl_->lines; }

std::size_t CarmenLogReader::skipped_lines() const { return impl_->skipped; }

double CarmenLogReader::progress() const {
  if (impl_->eof && impl_->buffer_pos >= impl_->buffer.size()) return 1.0;
  if (impl_->file_size == 0) return 1.0;
  const z_off_t offset = gzoffset(impl_->file.get());
  if (offset < 0) return 0.0;
  return std::clamp(static_cast<double>(offset) / static_cast<double>(impl_->file_size), 0.0, 1.0);
}

}  // namespace wm::logs
