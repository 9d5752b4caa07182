#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

#include "fusion/registration/plan_registration_internal.h"

namespace wm::fusion::internal {
namespace {

// The dominant directions of buildings turn the rotation search into a few candidates: length-weighted histograms of
// directions (mod π, 0.5° bins) of the drawn edges and of the occupied cells (from the second moments of their
// occupied neighbours, weighted by how line-like those are) are cross-correlated; each peak δ gives the rotations
// δ and δ + π. nullopt when the correlation has no clear peak (a round building, too little seen): then every
// angle is searched.
constexpr int kDirectionBins = 360;

void add_direction(std::vector<double>& histogram, double angle, double weight) {
  double bin = std::fmod(angle, kPi) / kPi * kDirectionBins;
  if (bin < 0) bin += kDirectionBins;
  const auto low = static_cast<int>(std::floor(bin)) % kDirectionBins;
  const double frac = bin - std::floor(bin);
  histogram[static_cast<std::size_t>(low)] += weight * (1 - frac);
  histogram[static_cast<std::size_t>((low + 1) % kDirectionBins)] += weight * frac;
}

std::vector<double> smoothed(const std::vector<double>& histogram) {
  std::vector<double> out(histogram.size(), 0.0);
  for (int i = 0; i < kDirectionBins; ++i)
    for (int d = -3; d <= 3; ++d)
      out[static_cast<std::size_t>(i)] +=
          std::exp(-0.5 * d * d) * histogram[static_cast<std::size_t>((i + d + kDirectionBins) % kDirectionBins)];
  return out;
}

}  // namespace

std::optional<std::vector<double>> direction_peaks(const std::vector<DrawnEdge>& edges, const ObservedMap& observed,
                                                   double occupied_probability) {
  std::vector<double> drawn(kDirectionBins, 0.0), seen(kDirectionBins, 0.0);
  for (const auto& e : edges) {
    const Eigen::Vector2d d = e.p1 - e.p0;
    if (d.norm() > 0) add_direction(drawn, std::atan2(d.y(), d.x()), d.norm());
  }
  const auto& g = observed.geometry;
  const auto occupied = [&](std::int64_t x, std::int64_t y) {
    return x >= 0 && y >= 0 && x < g.width() && y < g.height() &&
           observed.probability[static_cast<std::size_t>(y * g.width() + x)] > occupied_probability;
  };
  for (std::int64_t y = 0; y < g.height(); ++y)
    for (std::int64_t x = 0; x < g.width(); ++x) {
      if (!occupied(x, y)) continue;
      // The occupied neighbours within a disk of four cells: a square window, or a smaller disk, bends the
      // direction of a rasterised wall toward the grid's axes (a wall at 160° read as 150° with 5 × 5).
      double sxx = 0, syy = 0, sxy = 0;
      int n = 0;
      for (int dy = -4; dy <= 4; ++dy)
        for (int dx = -4; dx <= 4; ++dx)
          if ((dx || dy) && dx * dx + dy * dy <= 16 && occupied(x + dx, y + dy)) {
            sxx += dx * dx;
            syy += dy * dy;
            sxy += dx * dy;
            ++n;
          }
      if (n < 4) continue;
      const double anisotropy = std::hypot(sxx - syy, 2 * sxy) / (sxx + syy);
      add_direction(seen, 0.5 * std::atan2(2 * sxy, sxx - syy), anisotropy);
    }
  drawn = smoothed(drawn);
  seen = smoothed(seen);
  std::vector<double> correlation(kDirectionBins, 0.0);
  for (int k = 0; k < kDirectionBins; ++k)
    for (int i = 0; i < kDirectionBins; ++i)
      correlation[static_cast<std::size_t>(k)] +=
          seen[static_cast<std::size_t>((i + k) % kDirectionBins)] * drawn[static_cast<std::size_t>(i)];
  const double top = *std::max_element(correlation.begin(), correlation.end());
  const double mean = std::accumulate(correlation.begin(), correlation.end(), 0.0) / kDirectionBins;
  if (!(top > 1.5 * mean)) return std::nullopt;
  std::vector<std::pair<double, double>> peaks;  // (correlation, shift [rad])
  for (int k = 0; k < kDirectionBins; ++k) {
    const double c = correlation[static_cast<std::size_t>(k)];
    const double before = correlation[static_cast<std::size_t>((k + kDirectionBins - 1) % kDirectionBins)];
    const double after = correlation[static_cast<std::size_t>((k + 1) % kDirectionBins)];
    if (c < 0.5 * top || c < before || c <= after) continue;
    // Parabolic interpolation between the bins.
    const double curvature = before - 2 * c + after;
    const double offset = curvature < 0 ? 0.5 * (before - after) / curvature : 0.0;
    peaks.emplace_back(c, (k + offset) * kPi / kDirectionBins);
  }
  std::sort(peaks.begin(), peaks.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (peaks.size() > 4) peaks.resize(4);
  std::vector<double> shifts;
  for (const auto& p : peaks) shifts.push_back(p.second);
  return shifts;
}

}  // namespace wm::fusion::internal
