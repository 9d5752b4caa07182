// Scan alignment (fusion::align_scan_lines) on what a client and a map could hand it: any posted pose and
// covariance, any scan lines, any map lines, NaN and infinities included. The input is read as little-endian doubles:
// the pose (3), the covariance's upper triangle (6), then scan lines and map lines of 7 doubles each (two ends and a
// (ρ, φ) covariance's upper triangle), split where a count byte says. Expected: a result whose pose and covariance
// are finite (the posted ones when not aligned), or std::invalid_argument.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <vector>

#include "fusion/registration/scan_alignment.h"

namespace {

class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  bool has(std::size_t doubles) const { return size_ - at_ >= doubles * 8; }
  double next() {
    double value = 0;
    std::memcpy(&value, data_ + at_, 8);
    at_ += 8;
    return value;
  }
  std::uint8_t byte() { return at_ < size_ ? data_[at_++] : 0; }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t at_ = 0;
};

// A segment from 7 doubles; nullopt where the segment type refuses them (too short, not finite, not a covariance).
std::optional<wm::fusion::LineSegment> segment(Reader& in) {
  const Eigen::Vector2d a(in.next(), in.next()), b(in.next(), in.next());
  Eigen::Matrix2d cov;
  cov(0, 0) = in.next();
  cov(0, 1) = cov(1, 0) = in.next();
  cov(1, 1) = in.next();
  try {
    return wm::fusion::LineSegment::from_points(a, b, cov);
  } catch (const std::invalid_argument&) {
    return std::nullopt;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm::fusion;
  Reader in(data, size);
  const std::size_t scan_lines = in.byte() % 64;
  if (!in.has(9)) return 0;
  const Pose2D posted{in.next(), in.next(), in.next()};
  Eigen::Matrix3d cov;
  for (int r = 0; r < 3; ++r)
    for (int c = r; c < 3; ++c) cov(r, c) = cov(c, r) = in.next();
  std::vector<LineSegment> local;
  std::vector<AlignmentReference> references;
  for (std::size_t k = 0; in.has(7) && k < 256; ++k) {
    const auto s = segment(in);
    if (!s) continue;
    if (k < scan_lines)
      local.push_back(*s);
    else
      references.push_back({*s, k % 2 ? std::optional<double>(s->line.phi_rad) : std::nullopt});
  }
  try {
    const auto result = align_scan_lines(local, posted, cov, references);
    const bool finite = std::isfinite(result.pose.x_m) && std::isfinite(result.pose.y_m) &&
                        std::isfinite(result.pose.theta_rad) && result.cov.allFinite();
    if (!finite) std::abort();
    if (!result.aligned && (result.pose.x_m != posted.x_m || result.pose.theta_rad != posted.theta_rad)) std::abort();
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
