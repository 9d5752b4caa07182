#include "fusion/grid/grid_geometry.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace wm::fusion {
namespace {

// Indices beyond 2^52 can no longer be told apart in a double, so cell_of refuses them.
constexpr double kMaxIndex = 4503599627370496.0;

}  // namespace

GridGeometry::GridGeometry(Eigen::Vector2d origin_m, double resolution_m, std::int64_t width, std::int64_t height)
    : origin_m_(std::move(origin_m)), resolution_m_(resolution_m), width_(width), height_(height) {
  if (!origin_m_.allFinite()) throw std::invalid_argument("GridGeometry: origin_m must be finite");
  if (!(resolution_m_ > 0.0 && resolution_m_ <= kMaxResolutionM)) {
    throw std::invalid_argument("GridGeometry: resolution_m must be in (0, 100], got " + std::to_string(resolution_m_));
  }
  if (width_ <= 0 || width_ > kMaxSizeCells || height_ <= 0 || height_ > kMaxSizeCells) {
    throw std::invalid_argument("GridGeometry: width and height must be in [1, 1000000], got " +
                                std::to_string(width_) + " x " + std::to_string(height_));
  }
}

CellIndex GridGeometry::cell_of(const Eigen::Vector2d& p) const {
  const double fx = std::floor((p.x() - origin_m_.x()) / resolution_m_);
  const double fy = std::floor((p.y() - origin_m_.y()) / resolution_m_);
  // The negated comparisons also reject NaN.
  if (!(std::abs(fx) <= kMaxIndex && std::abs(fy) <= kMaxIndex)) {
    throw std::out_of_range("GridGeometry::cell_of: point is not finite or too far from the origin");
  }
  return {static_cast<std::int64_t>(fx), static_cast<std::int64_t>(fy)};
}

Eigen::Vector2d GridGeometry::center_of(CellIndex c) const {
  return origin_m_ + resolution_m_ * Eigen::Vector2d(static_cast<double>(c.x) + 0.5, static_cast<double>(c.y) + 0.5);
}

namespace {

std::int64_t checked_index(double f, const char* what) {
  // The negated comparison also rejects NaN.
  if (!(std::abs(f) <= kMaxIndex)) throw std::out_of_range(std::string(what) + ": point is not finite or too far");
  return static_cast<std::int64_t>(f);
}

void require_resolution(double resolution_m, const char* what) {
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m))
    throw std::invalid_argument(std::string(what) + ": resolution_m must be finite and > 0");
}

}  // namespace

GridGeometry CellRange::geometry(double resolution_m) const {
  return GridGeometry({static_cast<double>(first.x) * resolution_m, static_cast<double>(first.y) * resolution_m},
                      resolution_m, width(), height());
}

CellIndex cell_at(const Eigen::Vector2d& p, double resolution_m) {
  require_resolution(resolution_m, "cell_at");
  return {checked_index(std::floor(p.x() / resolution_m), "cell_at"),
          checked_index(std::floor(p.y() / resolution_m), "cell_at")};
}

CellRange covering(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, double resolution_m) {
  require_resolution(resolution_m, "covering");
  if (!(lo.x() <= hi.x() && lo.y() <= hi.y())) throw std::invalid_argument("covering: lo must be <= hi");
  return {{checked_index(std::floor(lo.x() / resolution_m), "covering"),
           checked_index(std::floor(lo.y() / resolution_m), "covering")},
          {checked_index(std::ceil(hi.x() / resolution_m), "covering"),
           checked_index(std::ceil(hi.y() / resolution_m), "covering")}};
}

bool GridGeometry::contains(CellIndex c) const { return c.x >= 0 && c.x < width_ && c.y >= 0 && c.y < height_; }

}  // namespace wm::fusion
