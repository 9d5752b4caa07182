#include "fusion/grid_lines/hough.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "fusion/geometry/line.h"
#include "fusion/grid_lines/internal/hough_accumulator.h"
#include "fusion/grid_lines/internal/raster_frame.h"

namespace wm::fusion {
namespace {

[[noreturn]] void fail(const std::string& message) {
  throw std::invalid_argument("validate(HoughOptions): " + message);
}

}  // namespace

void validate(const HoughOptions& options) {
  if (!(options.rho_step_cells >= 0.25 && options.rho_step_cells <= 16.0)) fail("rho_step_cells must be in [0.25, 16]");
  if (!(options.theta_step_rad >= 1e-4 && options.theta_step_rad <= std::numbers::pi / 8)) {
    fail("theta_step_rad must be in [1e-4, π/8]");
  }
  if (!(options.min_votes > 0.0) || !std::isfinite(options.min_votes)) fail("min_votes must be finite and > 0");
  if (!(options.nms_rho_m >= 0.0) || !std::isfinite(options.nms_rho_m)) fail("nms_rho_m must be finite and >= 0");
  if (!(options.nms_theta_rad >= 0.0 && options.nms_theta_rad <= std::numbers::pi / 2)) {
    fail("nms_theta_rad must be in [0, π/2]");
  }
  if (!(options.ambiguous_ratio > 0.0) || !std::isfinite(options.ambiguous_ratio)) {
    fail("ambiguous_ratio must be finite and > 0");
  }
  if (!(options.grey_min_p > 0.0f && options.grey_min_p <= 1.0f)) fail("grey_min_p must be in (0, 1]");
}

std::vector<HoughPeak> hough_peaks(const ProbabilityRaster& raster, std::span<const std::uint8_t> image,
                                   const HoughOptions& options, HoughWeighting weighting) {
  validate(options);
  validate(raster);
  if (image.size() != raster.p.size()) {
    throw std::invalid_argument("hough_peaks: image has " + std::to_string(image.size()) + " pixels, the raster " +
                                std::to_string(raster.p.size()));
  }
  const std::int64_t width = raster.geometry.width();
  internal::HoughAccumulator acc(width, raster.geometry.height(), options.rho_step_cells, options.theta_step_rad);
  acc.vote_cells(image.size(), [&](std::size_t i) {
    if (image[i] == 0) return 0.0f;
    if (weighting == HoughWeighting::binary) return 1.0f;
    return std::isnan(raster.p[i]) ? 0.0f : raster.p[i];  // unknown cells vote nothing
  });

  const internal::NmsWindow window = internal::nms_window(acc, raster.geometry.resolution_m(), options);
  std::vector<HoughPeak> peaks;
  internal::GreyVotes grey(acc, raster, options.grey_min_p);
  for (const internal::HoughBin& b : internal::nms_peaks(acc, static_cast<float>(options.min_votes), window)) {
    const internal::ResolvedPeak resolved =
        internal::resolve_ambiguity(acc, b, window, options.ambiguous_ratio, {}, grey);
    const LineFeature line = internal::world_line(acc.line(resolved.bin), raster.geometry);
    peaks.push_back({line.rho_m, line.phi_rad, acc.at(resolved.bin), resolved.ambiguous});
  }
  return peaks;
}

}  // namespace wm::fusion
