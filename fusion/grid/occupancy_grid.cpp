#include "fusion/grid/occupancy_grid.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "fusion/grid/internal/beam_walk.h"

namespace wm::fusion {

/// Structure of arrays: the Bayes update touches only stamp, scan_log_odds and log_odds, the DS update only
/// stamp, scan_o/scan_e and m_o/m_e/conflict, so each model streams through just its own bytes.
struct OccupancyGrid::Tile {
  Tile(TileIndex i, std::size_t n)
      : index(i), log_odds(n, 0.f), m_o(n, 0.f), m_e(n, 0.f), conflict(n, 0.f), stamp(n, 0u), scan_log_odds(n),
        scan_o(n), scan_e(n) {}

  TileIndex index;
  std::vector<float> log_odds;
  std::vector<float> m_o, m_e, conflict;
  std::vector<std::uint32_t> stamp;  // == the grid's stamp_: this scan already wrote scan_* for the cell
  std::vector<float> scan_log_odds;  // the scan's strongest Bayes increment so far
  std::vector<float> scan_o, scan_e;  // the scan's beams combined so far (Dempster)
  bool dirty = false;
};

namespace {

constexpr double kMaxSensorCoordinateM = 1e7;  // 10'000 km: keeps every cell index far from int64 overflow
constexpr double kTotalConflict = 1.0 - 1e-12;

// Dempster's rule without validation, for the update loop; false on total conflict (o, e untouched).
inline bool combine(double& o, double& e, double& k, double bo, double be) {
  const double u = 1.0 - o - e;
  const double bu = 1.0 - bo - be;
  k = o * be + e * bo;
  if (k >= kTotalConflict) return false;
  const double n = 1.0 / (1.0 - k);
  const double no = (o * bo + o * bu + u * bo) * n;
  const double ne = (e * be + e * bu + u * be) * n;
  o = no;
  e = ne;
  return true;
}

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("OccupancyGrid: " + what);
}

}  // namespace

OccupancyGrid::OccupancyGrid(const GridOptions& options) : options_(options) {
  require(options_.resolution_m >= 1e-3 && options_.resolution_m <= GridGeometry::kMaxResolutionM,
          "resolution_m must be in [0.001, 100]");
  const std::int64_t t = options_.tile_size_cells;
  require(t >= 4 && t <= 1024 && std::has_single_bit(static_cast<std::uint64_t>(t)),
          "tile_size_cells must be a power of two in [4, 1024]");
  require(std::isfinite(options_.log_odds_min) && options_.log_odds_min < 0.0, "log_odds_min must be finite and < 0");
  require(std::isfinite(options_.log_odds_max) && options_.log_odds_max > 0.0, "log_odds_max must be finite and > 0");
  require(options_.update_bayes || options_.update_ds, "at least one of update_bayes, update_ds must be set");
  validate(options_.sensor);
  shift_ = std::countr_zero(static_cast<std::uint64_t>(t));
  mask_ = t - 1;
}

OccupancyGrid::~OccupancyGrid() = default;

// The tile cache points into tiles_: a moved-from grid must not keep it.
OccupancyGrid::OccupancyGrid(OccupancyGrid&& other) noexcept
    : options_(other.options_),
      shift_(other.shift_),
      mask_(other.mask_),
      tiles_(std::move(other.tiles_)),
      tile_bounds_(std::exchange(other.tile_bounds_, std::nullopt)),
      cache_(std::exchange(other.cache_, {})),
      stamp_(other.stamp_),
      dirty_(std::move(other.dirty_)) {
  other.tiles_.clear();
  other.dirty_.clear();
}

OccupancyGrid& OccupancyGrid::operator=(OccupancyGrid&& other) noexcept {
  if (this != &other) {
    options_ = other.options_;
    shift_ = other.shift_;
    mask_ = other.mask_;
    tiles_ = std::move(other.tiles_);
    tile_bounds_ = std::exchange(other.tile_bounds_, std::nullopt);
    cache_ = std::exchange(other.cache_, {});
    stamp_ = other.stamp_;
    dirty_ = std::move(other.dirty_);
    touched_.clear();
    other.tiles_.clear();
    other.dirty_.clear();
  }
  return *this;
}

OccupancyGrid::OccupancyGrid(const OccupancyGrid& other)
    : options_(other.options_),
      shift_(other.shift_),
      mask_(other.mask_),
      tile_bounds_(other.tile_bounds_),
      stamp_(other.stamp_),
      dirty_(other.dirty_) {
  for (const auto& [index, tile] : other.tiles_) tiles_.emplace(index, std::make_unique<Tile>(*tile));
}

OccupancyGrid& OccupancyGrid::operator=(const OccupancyGrid& other) {
  if (this != &other) {
    OccupancyGrid copy(other);
    *this = std::move(copy);
  }
  return *this;
}

void OccupancyGrid::insert(const LaserScan& scan) {
  validate(scan);
  insert_scan(scan, scan.ranges_m.size(), [&](std::size_t i) { return laser_beam(scan, i, options_.sensor); });
}

void OccupancyGrid::insert(const SonarScan& scan) {
  validate(scan);
  insert_scan(scan, scan.ranges_m.size(), [&](std::size_t i) { return sonar_beam(scan, i, options_.sensor); });
}

template <typename ScanT, typename MakeBeam>
void OccupancyGrid::insert_scan(const ScanT& scan, std::size_t beams, const MakeBeam& make_beam) {
  const Pose2D& pose = scan.sensor_pose;
  if (std::abs(pose.x_m) > kMaxSensorCoordinateM || std::abs(pose.y_m) > kMaxSensorCoordinateM) {
    throw std::invalid_argument("OccupancyGrid::insert: sensor position is more than 10000 km from the origin");
  }
  // Everything the scan can touch lies within this radius of the sensor; refuse before changing anything.
  const double reach_m = std::min(scan.range_max_m, options_.sensor.max_usable_range_m) *
                             (1.0 + options_.sensor.sonar_sigma_per_range) +
                         scan.sigma_range_m + 2.0 * options_.resolution_m;
  const double tile_m = options_.resolution_m * static_cast<double>(options_.tile_size_cells);
  check_growth(static_cast<std::int64_t>(std::floor((pose.x_m - reach_m) / tile_m)),
               static_cast<std::int64_t>(std::floor((pose.y_m - reach_m) / tile_m)),
               static_cast<std::int64_t>(std::floor((pose.x_m + reach_m) / tile_m)),
               static_cast<std::int64_t>(std::floor((pose.y_m + reach_m) / tile_m)));

  if (++stamp_ == 0) {
    // 2^32 scans later: forget the old stamps rather than mistake one for the current scan.
    for (auto& [index, tile] : tiles_) std::fill(tile->stamp.begin(), tile->stamp.end(), 0u);
    stamp_ = 1;
  }
  touched_.clear();
  for (std::size_t i = 0; i < beams; ++i) {
    if (const std::optional<Beam> beam = make_beam(i)) walk(*beam);
  }
  finish_scan();
}

void OccupancyGrid::check_growth(std::int64_t tx0, std::int64_t ty0, std::int64_t tx1, std::int64_t ty1) const {
  if (tile_bounds_) {
    tx0 = std::min(tx0, (*tile_bounds_)[0]);
    ty0 = std::min(ty0, (*tile_bounds_)[1]);
    tx1 = std::max(tx1, (*tile_bounds_)[2]);
    ty1 = std::max(ty1, (*tile_bounds_)[3]);
  }
  const std::int64_t max_tiles = GridGeometry::kMaxSizeCells / options_.tile_size_cells;
  if (tx1 - tx0 + 1 > max_tiles || ty1 - ty0 + 1 > max_tiles) {
    throw std::invalid_argument("OccupancyGrid: the grid would grow beyond " +
                                std::to_string(GridGeometry::kMaxSizeCells) + " cells per side");
  }
}

OccupancyGrid::Tile* OccupancyGrid::tile_for_write(std::int64_t tx, std::int64_t ty) {
  CacheEntry& slot = cache_[static_cast<std::size_t>((tx & 7) | ((ty & 7) << 3))];
  if (slot.tile != nullptr && slot.x == tx && slot.y == ty) return slot.tile;
  const TileIndex index{tx, ty};
  auto it = tiles_.find(index);
  if (it == tiles_.end()) {
    const auto n = static_cast<std::size_t>(options_.tile_size_cells * options_.tile_size_cells);
    it = tiles_.emplace(index, std::make_unique<Tile>(index, n)).first;
    if (!tile_bounds_) {
      tile_bounds_ = std::array<std::int64_t, 4>{tx, ty, tx, ty};
    } else {
      auto& b = *tile_bounds_;
      b = {std::min(b[0], tx), std::min(b[1], ty), std::max(b[2], tx), std::max(b[3], ty)};
    }
  }
  slot = {tx, ty, it->second.get()};
  return slot.tile;
}

void OccupancyGrid::walk(const Beam& beam) {
  const internal::PreparedBeam b = internal::prepare(beam, options_.resolution_m);
  const bool bayes = options_.update_bayes;
  const bool ds = options_.update_ds;
  const double miss_log_odds = b.log_odds_miss;
  // The current tile along the beam: consecutive cells almost always share it.
  std::int64_t cur_x = std::numeric_limits<std::int64_t>::min();
  std::int64_t cur_y = 0;
  Tile* tile = nullptr;

  internal::walk_cone(b.ox, b.oy, b.angle_rad, b.half_width_rad, b.walk_limit,
                      [&](std::int64_t x, std::int64_t y, double d2) {
    const internal::CellClass cls = internal::classify(b, x, y, d2);
    if (cls == internal::CellClass::skip) return;
    const std::int64_t tx = x >> shift_;
    const std::int64_t ty = y >> shift_;
    if (tx != cur_x || ty != cur_y || tile == nullptr) {
      tile = tile_for_write(tx, ty);
      cur_x = tx;
      cur_y = ty;
    }
    const auto idx = static_cast<std::uint32_t>(((y & mask_) << shift_) | (x & mask_));

    // The Gaussian factor, only where it can be non-zero (hits, and free cells just in front of the return).
    double g = 0.0;
    double d = 0.0;
    const bool near_return = cls == internal::CellClass::hit || d2 > b.tail_limit2;
    if (near_return && b.has_return) {
      d = std::sqrt(d2);
      g = internal::range_factor(b, cls, x, y, d);
    }
    const double w = internal::angular_weight(b, x, y, d2);
    const bool first = tile->stamp[idx] != stamp_;
    if (first) {
      tile->stamp[idx] = stamp_;
      touched_.push_back({tile, idx});
    }
    if (bayes) {
      const auto l = static_cast<float>(
          w * (cls == internal::CellClass::hit ? internal::bayes_hit_log_odds(b, g) : miss_log_odds));
      if (first) {
        tile->scan_log_odds[idx] = l;
      } else {
        // The strongest hit if any beam hit the cell, else the strongest miss.
        const float old = tile->scan_log_odds[idx];
        tile->scan_log_odds[idx] = (old > 0.f || l > 0.f) ? std::max(old, l) : std::min(old, l);
      }
    }
    if (ds) {
      const internal::CellMasses m = internal::ds_masses(b, g, d, w);
      if (first) {
        tile->scan_o[idx] = static_cast<float>(m.occupied);
        tile->scan_e[idx] = static_cast<float>(m.empty);
      } else {
        double o = tile->scan_o[idx];
        double e = tile->scan_e[idx];
        double k = 0.0;
        // Beam masses are never certain (validated options), so a total conflict here is only float rounding:
        // keep what the scan had.
        if (combine(o, e, k, m.occupied, m.empty)) {
          tile->scan_o[idx] = static_cast<float>(o);
          tile->scan_e[idx] = static_cast<float>(e);
        }
      }
    }
  });
}

void OccupancyGrid::finish_scan() {
  const float lo = static_cast<float>(options_.log_odds_min);
  const float hi = static_cast<float>(options_.log_odds_max);
  for (const Touched& t : touched_) {
    Tile& tile = *t.tile;
    const std::uint32_t i = t.index;
    if (options_.update_bayes) tile.log_odds[i] = std::clamp(tile.log_odds[i] + tile.scan_log_odds[i], lo, hi);
    if (options_.update_ds) {
      double o = tile.m_o[i];
      double e = tile.m_e[i];
      double k = 0.0;
      if (combine(o, e, k, tile.scan_o[i], tile.scan_e[i])) {
        tile.m_o[i] = static_cast<float>(o);
        tile.m_e[i] = static_cast<float>(e);
      } else {
        k = 1.0;
      }
      tile.conflict[i] = std::max(tile.conflict[i], static_cast<float>(k));
    }
    if (!tile.dirty) {
      tile.dirty = true;
      dirty_.push_back(tile.index);
    }
  }
  touched_.clear();
}

std::optional<GridGeometry> OccupancyGrid::bounds() const {
  if (!tile_bounds_) return std::nullopt;
  const auto& b = *tile_bounds_;
  const std::int64_t t = options_.tile_size_cells;
  const double tile_m = options_.resolution_m * static_cast<double>(t);
  return GridGeometry({static_cast<double>(b[0]) * tile_m, static_cast<double>(b[1]) * tile_m}, options_.resolution_m,
                      (b[2] - b[0] + 1) * t, (b[3] - b[1] + 1) * t);
}

const OccupancyGrid::Tile* OccupancyGrid::find_tile(std::int64_t tx, std::int64_t ty) const {
  const auto it = tiles_.find(TileIndex{tx, ty});
  return it == tiles_.end() ? nullptr : it->second.get();
}

std::pair<const OccupancyGrid::Tile*, std::size_t> OccupancyGrid::locate(CellIndex c) const {
  const Tile* tile = find_tile(c.x >> shift_, c.y >> shift_);
  return {tile, static_cast<std::size_t>(((c.y & mask_) << shift_) | (c.x & mask_))};
}

double OccupancyGrid::log_odds(CellIndex c) const {
  const auto [tile, i] = locate(c);
  return tile == nullptr ? 0.0 : tile->log_odds[i];
}

double OccupancyGrid::probability(CellIndex c) const { return 1.0 - 1.0 / (1.0 + std::exp(log_odds(c))); }

OccupancyGrid::Masses OccupancyGrid::masses(CellIndex c) const {
  const auto [tile, i] = locate(c);
  if (tile == nullptr) return {0.0, 0.0, 1.0};
  const double o = tile->m_o[i];
  const double e = tile->m_e[i];
  return {o, e, std::max(0.0, 1.0 - o - e)};
}

double OccupancyGrid::belief(CellIndex c) const { return masses(c).occupied; }

double OccupancyGrid::plausibility(CellIndex c) const { return 1.0 - masses(c).empty; }

double OccupancyGrid::conflict(CellIndex c) const {
  const auto [tile, i] = locate(c);
  return tile == nullptr ? 0.0 : tile->conflict[i];
}

std::vector<TileIndex> OccupancyGrid::take_dirty_tiles() {
  std::vector<TileIndex> out;
  out.swap(dirty_);
  for (const TileIndex& t : out) tiles_.at(t)->dirty = false;
  std::sort(out.begin(), out.end());
  return out;
}

std::optional<OccupancyGrid::TileData> OccupancyGrid::tile(TileIndex t) const {
  const Tile* tile = find_tile(t.x, t.y);
  if (tile == nullptr) return std::nullopt;
  return TileData{tile->log_odds, tile->m_o, tile->m_e, tile->conflict};
}

void OccupancyGrid::set_tile(TileIndex t, TileData data) {
  const auto n = static_cast<std::size_t>(options_.tile_size_cells * options_.tile_size_cells);
  const auto fail = [](const std::string& what) {
    throw std::invalid_argument("OccupancyGrid::set_tile: " + what);
  };
  if (data.log_odds.size() != n || data.m_occupied.size() != n || data.m_empty.size() != n ||
      data.conflict.size() != n) {
    fail("every layer must hold tile_size_cells^2 = " + std::to_string(n) + " values");
  }
  constexpr float kSlack = 1e-5f;  // float rounding of masses that sum to 1
  for (std::size_t i = 0; i < n; ++i) {
    const float l = data.log_odds[i];
    const float o = data.m_occupied[i];
    const float e = data.m_empty[i];
    const float k = data.conflict[i];
    if (!std::isfinite(l) || !std::isfinite(o) || !std::isfinite(e) || !std::isfinite(k)) {
      fail("values must be finite (cell " + std::to_string(i) + ")");
    }
    if (o < 0.f || o > 1.f || e < 0.f || e > 1.f || o + e > 1.f + kSlack || k < 0.f || k > 1.f) {
      fail("masses and conflict must be in [0, 1] with m_occupied + m_empty <= 1 (cell " + std::to_string(i) + ")");
    }
  }
  check_growth(t.x, t.y, t.x, t.y);
  Tile* tile = tile_for_write(t.x, t.y);
  const float lo = static_cast<float>(options_.log_odds_min);
  const float hi = static_cast<float>(options_.log_odds_max);
  for (float& l : data.log_odds) l = std::clamp(l, lo, hi);
  tile->log_odds = std::move(data.log_odds);
  tile->m_o = std::move(data.m_occupied);
  tile->m_e = std::move(data.m_empty);
  tile->conflict = std::move(data.conflict);
}

std::vector<TileIndex> OccupancyGrid::tiles() const {
  std::vector<TileIndex> out;
  out.reserve(tiles_.size());
  for (const auto& [index, tile] : tiles_) out.push_back(index);
  return out;
}

std::vector<float> OccupancyGrid::export_layer(Layer layer, const GridGeometry& region) const {
  if (region.width() > kMaxExportCells / region.height()) {
    throw std::invalid_argument("OccupancyGrid::export_layer: region has more than " +
                                std::to_string(kMaxExportCells) + " cells");
  }
  const auto w = static_cast<std::size_t>(region.width());
  const auto h = static_cast<std::size_t>(region.height());
  std::vector<float> out(w * h, std::numeric_limits<float>::quiet_NaN());
  const GridGeometry own({0.0, 0.0}, options_.resolution_m, 1, 1);
  const Tile* tile = nullptr;
  std::int64_t cur_x = std::numeric_limits<std::int64_t>::min();
  std::int64_t cur_y = 0;
  for (std::size_t row = 0; row < h; ++row) {
    for (std::size_t col = 0; col < w; ++col) {
      const Eigen::Vector2d p =
          region.center_of({static_cast<std::int64_t>(col), static_cast<std::int64_t>(row)});
      CellIndex c;
      try {
        c = own.cell_of(p);
      } catch (const std::out_of_range&) {
        continue;  // so far out that no tile can be there
      }
      const std::int64_t tx = c.x >> shift_;
      const std::int64_t ty = c.y >> shift_;
      if (tx != cur_x || ty != cur_y) {
        tile = find_tile(tx, ty);
        cur_x = tx;
        cur_y = ty;
      }
      if (tile == nullptr) continue;
      const auto i = static_cast<std::size_t>(((c.y & mask_) << shift_) | (c.x & mask_));
      const float o = tile->m_o[i];
      const float e = tile->m_e[i];
      const bool ds_unknown = o == 0.f && e == 0.f;
      float v = std::numeric_limits<float>::quiet_NaN();
      switch (layer) {
        case Layer::bayes_probability:
          if (tile->log_odds[i] != 0.f) v = 1.f - 1.f / (1.f + std::exp(tile->log_odds[i]));
          break;
        case Layer::ds_belief:
          if (!ds_unknown) v = o;
          break;
        case Layer::ds_plausibility:
          if (!ds_unknown) v = 1.f - e;
          break;
        case Layer::ds_conflict:
          if (!ds_unknown) v = tile->conflict[i];
          break;
      }
      out[row * w + col] = v;
    }
  }
  return out;
}

DempsterResult dempster_combine(const OccupancyGrid::Masses& a, const OccupancyGrid::Masses& b) {
  for (const auto* m : {&a, &b}) {
    const bool finite = std::isfinite(m->occupied) && std::isfinite(m->empty) && std::isfinite(m->unknown);
    const bool in_range = m->occupied >= 0.0 && m->occupied <= 1.0 && m->empty >= 0.0 && m->empty <= 1.0 &&
                          m->unknown >= 0.0 && m->unknown <= 1.0;
    if (!finite || !in_range || std::abs(m->occupied + m->empty + m->unknown - 1.0) > 1e-6) {
      throw std::invalid_argument("dempster_combine: masses must be finite, in [0, 1] and sum to 1");
    }
  }
  const double k = a.occupied * b.empty + a.empty * b.occupied;
  if (k >= kTotalConflict) return {std::nullopt, k};
  const double n = 1.0 / (1.0 - k);
  OccupancyGrid::Masses m{(a.occupied * b.occupied + a.occupied * b.unknown + a.unknown * b.occupied) * n,
                          (a.empty * b.empty + a.empty * b.unknown + a.unknown * b.empty) * n,
                          a.unknown * b.unknown * n};
  return {m, k};
}

}  // namespace wm::fusion
