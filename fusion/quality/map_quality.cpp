#include "fusion/quality/map_quality.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <unordered_map>
#include <vector>

namespace wm::fusion {
namespace {

struct Ends {
  Eigen::Vector2d p0, p1;
  double length = 0;
  double phi = 0;
};

double distance_to_segment(const Eigen::Vector2d& p, const Ends& s) {
  const Eigen::Vector2d d = s.p1 - s.p0;
  const double len2 = d.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - s.p0).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (p - (s.p0 + t * d)).norm();
}

// Angle between two undirected directions, in [0, π/2].
double direction_difference(double phi_a, double phi_b) {
  const double diff = std::fmod(std::abs(phi_a - phi_b), std::numbers::pi);
  return std::min(diff, std::numbers::pi - diff);
}

// Calls visit(point, weight) for n evenly spaced samples covering the segment, each standing for length/n.
template <typename Visit>
void for_each_sample(const Ends& s, double step, const Visit& visit) {
  if (s.length <= 0) return;
  const auto n = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(s.length / step)));
  const double weight = s.length / static_cast<double>(n);
  for (std::int64_t k = 0; k < n; ++k) {
    const double t = (static_cast<double>(k) + 0.5) / static_cast<double>(n);
    visit(Eigen::Vector2d(s.p0 + t * (s.p1 - s.p0)), weight);
  }
}

class OccupiedRaster {
 public:
  OccupiedRaster(const GridGeometry& geometry, std::span<const float> probabilities, double threshold)
      : geometry_(geometry), occupied_(probabilities.size()) {
    for (std::size_t i = 0; i < probabilities.size(); ++i) {
      // NaN (unknown) compares false: never occupied.
      occupied_[i] = probabilities[i] > threshold;
      count_ += occupied_[i];
    }
  }
  bool occupied(std::int64_t x, std::int64_t y) const {
    return geometry_.contains({x, y}) && occupied_[static_cast<std::size_t>(y * geometry_.width() + x)];
  }
  bool occupied_near(const Eigen::Vector2d& p) const {
    const CellIndex c = geometry_.cell_of(p);
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dx = -1; dx <= 1; ++dx)
        if (occupied(c.x + dx, c.y + dy)) return true;
    return false;
  }
  std::size_t count() const { return count_; }
  const GridGeometry& geometry() const { return geometry_; }
  const std::vector<char>& cells() const { return occupied_; }

 private:
  const GridGeometry& geometry_;
  std::vector<char> occupied_;
  std::size_t count_ = 0;
};

// Occupied cells with an element within `radius` of their centre, found by walking each element in half-cell steps
// and testing the cells around each step exactly (linear in element length, not in the raster).
std::size_t explained_cells(const OccupiedRaster& raster, const std::vector<Ends>& elements, double radius) {
  const GridGeometry& g = raster.geometry();
  std::vector<char> explained(raster.cells().size(), 0);
  const double step = g.resolution_m() / 2;
  const auto reach = static_cast<std::int64_t>(std::ceil(radius / g.resolution_m())) + 1;
  for (const auto& e : elements) {
    const auto n = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(e.length / step)));
    for (std::int64_t k = 0; k <= n; ++k) {
      const Eigen::Vector2d p = e.p0 + (static_cast<double>(k) / static_cast<double>(n)) * (e.p1 - e.p0);
      const CellIndex c = g.cell_of(p);
      for (std::int64_t y = c.y - reach; y <= c.y + reach; ++y) {
        for (std::int64_t x = c.x - reach; x <= c.x + reach; ++x) {
          if (!raster.occupied(x, y)) continue;
          const auto i = static_cast<std::size_t>(y * g.width() + x);
          if (!explained[i] && distance_to_segment(g.center_of({x, y}), e) <= radius) explained[i] = 1;
        }
      }
    }
  }
  return static_cast<std::size_t>(std::count(explained.begin(), explained.end(), 1));
}

// Elements by the buckets of a uniform grid their extent (grown by `margin`) overlaps.
class Buckets {
 public:
  Buckets(const std::vector<Ends>& elements, double size, double margin) : size_(size) {
    for (std::size_t i = 0; i < elements.size(); ++i) {
      const auto& e = elements[i];
      const Eigen::Vector2d lo = e.p0.cwiseMin(e.p1).array() - margin;
      const Eigen::Vector2d hi = e.p0.cwiseMax(e.p1).array() + margin;
      for (auto by = index(lo.y()); by <= index(hi.y()); ++by)
        for (auto bx = index(lo.x()); bx <= index(hi.x()); ++bx) buckets_[key(bx, by)].push_back(i);
    }
  }
  const std::vector<std::size_t>* at(const Eigen::Vector2d& p) const {
    const auto it = buckets_.find(key(index(p.x()), index(p.y())));
    return it == buckets_.end() ? nullptr : &it->second;
  }

 private:
  std::int64_t index(double v) const { return static_cast<std::int64_t>(std::floor(v / size_)); }
  static std::uint64_t key(std::int64_t bx, std::int64_t by) {
    return (static_cast<std::uint64_t>(bx) << 32) ^ static_cast<std::uint64_t>(by & 0xffffffff);
  }
  double size_;
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> buckets_;
};

void check(const GridGeometry& raster, std::span<const float> probabilities, const MapQualityOptions& o) {
  if (static_cast<std::int64_t>(probabilities.size()) != raster.width() * raster.height())
    throw std::invalid_argument("map_quality: the raster has width·height cells, the probabilities do not match");
  const bool ok = o.sample_step_m > 0 && o.occupied_probability > 0 && o.occupied_probability < 1 &&
                  o.recall_radius_m > 0 && o.redundancy_offset_m >= 0 && o.redundancy_angle_rad >= 0 &&
                  o.redundancy_angle_rad <= std::numbers::pi / 2;
  if (!ok) throw std::invalid_argument("map_quality: an option is out of range (see MapQualityOptions)");
}

}  // namespace

MapQuality map_quality(std::span<const LineSegment> segments, const GridGeometry& raster,
                       std::span<const float> probabilities, const MapQualityOptions& options) {
  check(raster, probabilities, options);
  std::vector<Ends> elements;
  elements.reserve(segments.size());
  for (const auto& s : segments) {
    elements.push_back({s.p0(), s.p1(), std::max(0.0, s.t1_m - s.t0_m), s.line.phi_rad});
  }
  MapQuality q;
  q.elements = elements.size();
  std::vector<double> lengths;
  lengths.reserve(elements.size());
  for (const auto& e : elements) {
    q.total_length_m += e.length;
    lengths.push_back(e.length);
  }
  if (!lengths.empty()) {
    const auto middle = lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2);
    std::nth_element(lengths.begin(), middle, lengths.end());
    q.median_length_m = *middle;
    if (lengths.size() % 2 == 0)
      q.median_length_m = (q.median_length_m + *std::max_element(lengths.begin(), middle)) / 2;
  }
  if (q.total_length_m > 0) q.elements_per_m = static_cast<double>(q.elements) / q.total_length_m;

  const OccupiedRaster occupied(raster, probabilities, options.occupied_probability);
  q.occupied_cells = occupied.count();
  if (q.occupied_cells > 0) {
    q.recall = static_cast<double>(explained_cells(occupied, elements, options.recall_radius_m)) /
               static_cast<double>(q.occupied_cells);
  }

  // Buckets of 1 m: small against a building, large against the 5 cm offset, so a sample needs one bucket only.
  const Buckets buckets(elements, 1.0, options.redundancy_offset_m);
  double backed = 0, redundant = 0;
  for (std::size_t i = 0; i < elements.size(); ++i) {
    const auto& e = elements[i];
    for_each_sample(e, options.sample_step_m, [&](const Eigen::Vector2d& p, double weight) {
      if (occupied.occupied_near(p)) backed += weight;
      const auto* nearby = buckets.at(p);
      if (!nearby) return;
      for (const auto j : *nearby) {
        if (j == i || elements[j].length <= 0) continue;
        if (direction_difference(e.phi, elements[j].phi) > options.redundancy_angle_rad) continue;
        if (distance_to_segment(p, elements[j]) <= options.redundancy_offset_m) {
          redundant += weight;
          return;
        }
      }
    });
  }
  if (q.total_length_m > 0) {
    q.precision = backed / q.total_length_m;
    q.redundancy = redundant / q.total_length_m;
  }
  return q;
}

}  // namespace wm::fusion
