#include "fusion/grid_lines/internal/hough_accumulator.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace wm::fusion::internal {
namespace {

// Fixed point of the bin computation: 2^24 parts of a bin. Half-cell coordinates stay below 2^21 (width <= 10^6),
// the scaled cosines below 2^25 (Δρ >= 0.25 cells), so products stay below 2^46.
constexpr int kShift = 24;
constexpr std::int64_t kOne = std::int64_t{1} << kShift;

}  // namespace

HoughAccumulator::HoughAccumulator(std::int64_t width, std::int64_t height, double rho_step_cells,
                                   double theta_step_rad)
    : width_(width), height_(height), rho_step_(rho_step_cells) {
  if (width < 1 || height < 1 || width > kMaxRasterCells || height > kMaxRasterCells ||
      width * height > kMaxRasterCells) {
    throw std::invalid_argument("HoughAccumulator: raster size out of range");
  }
  if (!(rho_step_cells >= 0.25 && rho_step_cells <= 16.0)) {
    throw std::invalid_argument("HoughAccumulator: rho_step_cells must be in [0.25, 16]");
  }
  if (!(theta_step_rad >= 1e-4 && theta_step_rad <= std::numbers::pi / 8)) {
    throw std::invalid_argument("HoughAccumulator: theta_step_rad must be in [1e-4, π/8]");
  }
  theta_bins_ = static_cast<int>(std::lround(std::numbers::pi / theta_step_rad));
  theta_step_ = std::numbers::pi / theta_bins_;
  const double half_diagonal = 0.5 * std::hypot(static_cast<double>(width), static_cast<double>(height));
  r_center_ = static_cast<int>(std::ceil(half_diagonal / rho_step_)) + 1;
  rho_bins_ = 2 * r_center_ + 1;
  cos_fixed_.resize(static_cast<std::size_t>(theta_bins_));
  sin_fixed_.resize(static_cast<std::size_t>(theta_bins_));
  for (int t = 0; t < theta_bins_; ++t) {
    const double theta = theta_rad(t);
    cos_fixed_[static_cast<std::size_t>(t)] = std::llround(std::cos(theta) / (2.0 * rho_step_) * kOne);
    sin_fixed_[static_cast<std::size_t>(t)] = std::llround(std::sin(theta) / (2.0 * rho_step_) * kOne);
  }
  votes_.assign(static_cast<std::size_t>(theta_bins_) * static_cast<std::size_t>(rho_bins_), 0.0f);
}

double HoughAccumulator::theta_rad(int t) const { return t * theta_step_; }

double HoughAccumulator::rho_cells(int r) const { return (r - r_center_) * rho_step_; }

CellLine HoughAccumulator::line(HoughBin b) const {
  const double theta = theta_rad(b.t);
  return {std::cos(theta), std::sin(theta), rho_cells(b.r)};
}

int HoughAccumulator::rho_bin(int t, std::int64_t x, std::int64_t y) const {
  // Half-cell coordinates of the centre: 2·x_c = 2x + 1 − width.
  const std::int64_t hx = 2 * x + 1 - width_;
  const std::int64_t hy = 2 * y + 1 - height_;
  const std::int64_t offset = (static_cast<std::int64_t>(r_center_) << kShift) + kOne / 2;
  return static_cast<int>(
      (hx * cos_fixed_[static_cast<std::size_t>(t)] + hy * sin_fixed_[static_cast<std::size_t>(t)] + offset) >> kShift);
}

void HoughAccumulator::vote(std::span<const std::int32_t> xs, std::span<const std::int32_t> ys,
                            std::span<const float> weights) {
  if (xs.size() != ys.size() || (!weights.empty() && weights.size() != xs.size())) {
    throw std::invalid_argument("HoughAccumulator::vote: xs, ys and weights differ in size");
  }
  const std::size_t n = xs.size();
  std::vector<std::int64_t> hx(n), hy(n);
  for (std::size_t i = 0; i < n; ++i) {
    hx[i] = 2 * static_cast<std::int64_t>(xs[i]) + 1 - width_;
    hy[i] = 2 * static_cast<std::int64_t>(ys[i]) + 1 - height_;
  }
  const std::int64_t offset = (static_cast<std::int64_t>(r_center_) << kShift) + kOne / 2;
  // θ-major: one accumulator row (a few kB) stays in L1 while every pixel votes into it.
  for (int t = 0; t < theta_bins_; ++t) {
    const std::int64_t c = cos_fixed_[static_cast<std::size_t>(t)];
    const std::int64_t s = sin_fixed_[static_cast<std::size_t>(t)];
    float* row = votes_.data() + static_cast<std::size_t>(t) * static_cast<std::size_t>(rho_bins_);
    if (weights.empty()) {
      for (std::size_t i = 0; i < n; ++i) row[(hx[i] * c + hy[i] * s + offset) >> kShift] += 1.0f;
    } else {
      for (std::size_t i = 0; i < n; ++i) row[(hx[i] * c + hy[i] * s + offset) >> kShift] += weights[i];
    }
  }
}

void HoughAccumulator::add(std::int64_t x, std::int64_t y, float weight) {
  for (int t = 0; t < theta_bins_; ++t) {
    votes_[static_cast<std::size_t>(t) * static_cast<std::size_t>(rho_bins_) +
           static_cast<std::size_t>(rho_bin(t, x, y))] += weight;
  }
}

std::optional<HoughBin> HoughAccumulator::offset(HoughBin b, int dt, int dr) const {
  int t = b.t + dt;
  int r = b.r + dr;
  // θ and θ ± π are the same line with ρ negated: bin r ↔ 2R − r.
  while (t < 0) {
    t += theta_bins_;
    r = 2 * r_center_ - r;
  }
  while (t >= theta_bins_) {
    t -= theta_bins_;
    r = 2 * r_center_ - r;
  }
  if (r < 0 || r >= rho_bins_) return std::nullopt;
  return HoughBin{t, r};
}

bool HoughAccumulator::is_local_max(HoughBin b) const {
  const float v = at(b);
  if (!(v > 0.0f)) return false;
  for (int dt = -1; dt <= 1; ++dt) {
    for (int dr = -1; dr <= 1; ++dr) {
      if (dt == 0 && dr == 0) continue;
      if (const auto n = offset(b, dt, dr); n && at(*n) > v) return false;
    }
  }
  return true;
}

NmsWindow nms_window(const HoughAccumulator& acc, double resolution_m, const HoughOptions& options) {
  // Clamped to the accumulator: a wider window suppresses nothing more.
  const double dt = std::min(std::round(options.nms_theta_rad / acc.theta_step_rad()), 0.5 * acc.theta_bins());
  const double dr = std::min(std::round(options.nms_rho_m / (resolution_m * acc.rho_step_cells())),
                             static_cast<double>(acc.rho_bins()));
  return {static_cast<int>(dt), static_cast<int>(dr)};
}

std::vector<HoughBin> nms_peaks(const HoughAccumulator& acc, float min_votes, NmsWindow window) {
  std::vector<HoughBin> maxima;
  for (int t = 0; t < acc.theta_bins(); ++t) {
    for (int r = 0; r < acc.rho_bins(); ++r) {
      const HoughBin b{t, r};
      if (acc.at(b) >= min_votes && acc.is_local_max(b)) maxima.push_back(b);
    }
  }
  std::stable_sort(maxima.begin(), maxima.end(),
                   [&](const HoughBin& a, const HoughBin& b) { return acc.at(a) > acc.at(b); });
  std::vector<std::uint8_t> suppressed(acc.size(), 0);
  std::vector<HoughBin> peaks;
  for (const HoughBin& b : maxima) {
    if (suppressed[acc.index(b)] != 0) continue;
    peaks.push_back(b);
    for_each_in_window(acc, b, window, [&](HoughBin n) { suppressed[acc.index(n)] = 1; });
  }
  return peaks;
}

double GreyVotes::at(HoughBin b) {
  if (!votes_) {
    votes_.emplace(raster_.geometry.width(), raster_.geometry.height(), shape_.rho_step_cells(),
                   shape_.theta_step_rad());
    // Unknown (NaN) cells fail the comparison too.
    votes_->vote_cells(raster_.p.size(),
                       [&](std::size_t i) { return raster_.p[i] >= grey_min_p_ ? raster_.p[i] : 0.0f; });
  }
  return votes_->at(b);
}

ResolvedPeak resolve_ambiguity(const HoughAccumulator& acc, HoughBin peak, NmsWindow window, double ratio,
                               std::span<const std::uint8_t> excluded, GreyVotes& grey) {
  const double bar = ratio * acc.at(peak);
  std::vector<HoughBin> candidates{peak};
  for_each_in_window(acc, peak, window, [&](HoughBin b) {
    if (b == peak || acc.at(b) < bar) return;
    if (!excluded.empty() && excluded[acc.index(b)] != 0) return;
    if (acc.is_local_max(b)) candidates.push_back(b);
  });
  if (candidates.size() == 1) return {peak, false};
  HoughBin best = peak;
  double best_grey = -1.0;
  for (const HoughBin& b : candidates) {
    const double g = grey.at(b);
    if (g > best_grey) {
      best_grey = g;
      best = b;
    }
  }
  return {best, true};
}

}  // namespace wm::fusion::internal
