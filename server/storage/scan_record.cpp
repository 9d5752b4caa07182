#include "server/storage/scan_record.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "server/storage/database.h"

namespace wm::storage {
namespace {

static_assert(std::endian::native == std::endian::little, "the stored scan layout is little-endian");
constexpr char kMagic[4] = {'W', 'M', 'S', '1'};
constexpr std::uint8_t kLaser = 1, kSonar = 2;

class Writer {
 public:
  void bytes(const void* data, std::size_t n) {
    if (n > 0) out_.append(static_cast<const char*>(data), n);  // an empty vector's data() may be null
  }
  void f64(double v) { bytes(&v, sizeof v); }
  void u32(std::uint32_t v) { bytes(&v, sizeof v); }
  void u8(std::uint8_t v) { bytes(&v, sizeof v); }
  void f64s(const std::vector<double>& v) { bytes(v.data(), v.size() * sizeof(double)); }
  std::string take() { return std::move(out_); }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(std::string_view in) : in_(in) {}
  void bytes(void* data, std::size_t n) {
    if (n == 0) return;  // an empty vector's data() may be null, which memcpy must not get
    if (n > in_.size() - at_) throw StorageError("stored scan: truncated (" + std::to_string(in_.size()) + " bytes)");
    std::memcpy(data, in_.data() + at_, n);
    at_ += n;
  }
  double f64() {
    double v = 0;
    bytes(&v, sizeof v);
    return v;
  }
  std::uint32_t u32() {
    std::uint32_t v = 0;
    bytes(&v, sizeof v);
    return v;
  }
  std::uint8_t u8() {
    std::uint8_t v = 0;
    bytes(&v, sizeof v);
    return v;
  }
  std::size_t count() {
    const std::size_t n = u32();
    if (n > kMaxStoredReadings)
      throw StorageError("stored scan: " + std::to_string(n) + " readings, more than " +
                         std::to_string(kMaxStoredReadings));
    return n;
  }
  std::vector<double> f64s(std::size_t n) {
    if (n * sizeof(double) > in_.size() - at_)
      throw StorageError("stored scan: truncated (" + std::to_string(in_.size()) + " bytes)");
    std::vector<double> v(n);
    bytes(v.data(), n * sizeof(double));
    return v;
  }
  void expect_end() const {
    if (at_ != in_.size())
      throw StorageError("stored scan: " + std::to_string(in_.size() - at_) + " bytes left after the scan");
  }

 private:
  std::string_view in_;
  std::size_t at_ = 0;
};

void write_pose(Writer& w, const fusion::Pose2D& pose, const Eigen::Matrix3d& cov) {
  w.f64(pose.x_m);
  w.f64(pose.y_m);
  w.f64(pose.theta_rad);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) w.f64(cov(r, c));
}

void read_pose(Reader& r, fusion::Pose2D& pose, Eigen::Matrix3d& cov) {
  pose.x_m = r.f64();
  pose.y_m = r.f64();
  pose.theta_rad = r.f64();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) cov(i, j) = r.f64();
}

}  // namespace

std::string encode_scan(const world::ScanObservation& scan) {
  Writer w;
  w.bytes(kMagic, sizeof kMagic);
  if (const auto* laser = std::get_if<fusion::LaserScan>(&scan.scan)) {
    w.u8(kLaser);
    write_pose(w, laser->sensor_pose, scan.pose_cov);
    for (const double v : {laser->angle_min_rad, laser->angle_increment_rad, laser->range_min_m, laser->range_max_m,
                           laser->sigma_range_m, laser->sigma_range_per_m, laser->usable_range_m})
      w.f64(v);
    w.u32(static_cast<std::uint32_t>(laser->ranges_m.size()));
    w.f64s(laser->ranges_m);
  } else {
    const auto& sonar = std::get<fusion::SonarScan>(scan.scan);
    w.u8(kSonar);
    write_pose(w, sonar.sensor_pose, scan.pose_cov);
    for (const double v : {sonar.beam_width_rad, sonar.range_min_m, sonar.range_max_m, sonar.sigma_range_m}) w.f64(v);
    w.u32(static_cast<std::uint32_t>(sonar.ranges_m.size()));
    w.f64s(sonar.angles_rad);
    w.f64s(sonar.ranges_m);
  }
  return w.take();
}

world::ScanObservation decode_scan(std::string_view blob, std::string observer, double stamp_s) {
  Reader r(blob);
  char magic[4] = {};
  r.bytes(magic, sizeof magic);
  if (std::memcmp(magic, kMagic, sizeof magic) != 0) throw StorageError("stored scan: not a scan record");
  world::ScanObservation scan;
  scan.observer = std::move(observer);
  scan.stamp_s = stamp_s;
  const auto kind = r.u8();
  try {
    if (kind == kLaser) {
      fusion::LaserScan laser;
      read_pose(r, laser.sensor_pose, scan.pose_cov);
      laser.angle_min_rad = r.f64();
      laser.angle_increment_rad = r.f64();
      laser.range_min_m = r.f64();
      laser.range_max_m = r.f64();
      laser.sigma_range_m = r.f64();
      laser.sigma_range_per_m = r.f64();
      laser.usable_range_m = r.f64();
      laser.ranges_m = r.f64s(r.count());
      r.expect_end();
      fusion::validate(laser);
      scan.scan = std::move(laser);
    } else if (kind == kSonar) {
      fusion::SonarScan sonar;
      read_pose(r, sonar.sensor_pose, scan.pose_cov);
      sonar.beam_width_rad = r.f64();
      sonar.range_min_m = r.f64();
      sonar.range_max_m = r.f64();
      sonar.sigma_range_m = r.f64();
      const auto n = r.count();
      sonar.angles_rad = r.f64s(n);
      sonar.ranges_m = r.f64s(n);
      r.expect_end();
      fusion::validate(sonar);
      scan.scan = std::move(sonar);
    } else {
      throw StorageError("stored scan: unknown kind " + std::to_string(kind));
    }
  } catch (const std::invalid_argument& e) {
    throw StorageError(std::string("stored scan: ") + e.what());
  }
  if (!scan.pose_cov.allFinite()) throw StorageError("stored scan: the pose covariance is not finite");
  return scan;
}

}  // namespace wm::storage
