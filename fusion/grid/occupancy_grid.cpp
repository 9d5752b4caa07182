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

/// The DS layers of a cell: m(O), m(E) and the conflict layer, together because an update reads and writes all three.
struct OccupancyGrid::DsCell {
  float o = 0.f, e = 0.f, k = 0.f;
};

/// Only map values: what a scan needs to update each cell once lives in ScanScratch, so an update touches 4 bytes
/// (Bayes) or 12 bytes (DS) of the map per cell, once per scan.
struct OccupancyGrid::Tile {
  Tile(TileIndex i, std::size_t n) : index(i), log_odds(n), ds(n) {}

  TileIndex index;
  std::vector<float> log_odds;
  std::vector<DsCell> ds;
  std::uint32_t stamp = 0;     // last scan that touched the tile
  std::uint32_t scratch = 0;   // its ScanScratch in that scan (valid while stamp == the grid's stamp_)
  std::uint64_t revision = 0;  // inserts and restores that changed it (never reset, unlike the stamp)
  bool dirty = false;
};

/// One touched tile's evidence during a scan, beside the map: which cells the scan reached (a bitmap) and, for those
/// only, the strongest Bayes increment and the beams' DS masses combined so far. Reused from scan to scan; the
/// value arrays are never cleared (a cell's entry is written by the first beam to reach it, as its bit is set), the
/// bitmap is cleared as the scan is applied.
struct OccupancyGrid::ScanScratch {
  struct Masses {
    double o, e;
  };
  ScanScratch(std::size_t n, bool bayes, bool ds)
      : touched((n + 63) / 64),
        increment(bayes ? new float[n] : nullptr),  // uninitialised on purpose: read only where touched
        masses(ds ? new Masses[n] : nullptr) {}

  Tile* tile = nullptr;
  std::vector<std::uint64_t> touched;
  std::unique_ptr<float[]> increment;  // the scan's strongest hit, else its strongest miss [log-odds]
  std::unique_ptr<Masses[]> masses;    // the scan's beams, combined with Dempster's rule
};

namespace {

constexpr double kMaxSensorCoordinateM = 1e7;  // 10'000 km: keeps every cell index far from int64 overflow
constexpr double kTotalConflict = 1.0 - 1e-12;
// Scratch kept between scans: enough for the tiles a long-range laser scan touches at the default tile size; a scan
// that touches more allocates the rest and gives it back when applied.
constexpr std::size_t kKeptScratch = 64;

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
  require(options_.ds_unknown_min >= 0.0 && options_.ds_unknown_min < 1.0, "ds_unknown_min must be in [0, 1)");
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
      dirty_(std::move(other.dirty_)),
      scratch_(std::move(other.scratch_)),
      scratch_used_(std::exchange(other.scratch_used_, 0)) {
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
    scratch_ = std::move(other.scratch_);
    scratch_used_ = std::exchange(other.scratch_used_, 0);
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

void OccupancyGrid::insert(const SonarScan& scan, const std::vector<std::optional<Beam>>& beams) {
  validate(scan);
  if (beams.size() != scan.ranges_m.size())
    throw std::invalid_argument("OccupancyGrid::insert: " + std::to_string(beams.size()) + " beams for " +
                                std::to_string(scan.ranges_m.size()) + " readings");
  const double reach = std::min(scan.range_max_m, usable_range_m(scan, options_.sensor)) *
                       (1.0 + range_sigma_per_m(scan, options_.sensor));
  const Eigen::Vector2d sensor(scan.sensor_pose.x_m, scan.sensor_pose.y_m);
  for (const auto& beam : beams) {
    if (!beam) continue;
    if (!std::isfinite(beam->range_m) || beam->range_m < 0 || beam->range_m > reach || !std::isfinite(beam->sigma_m) ||
        (beam->origin_m - sensor).norm() > 1e-9 || beam->half_width_rad != scan.beam_width_rad / 2)
      throw std::invalid_argument(
          "OccupancyGrid::insert: a sonar beam is not one of the scan's (origin, width or range)");
  }
  insert_scan(scan, beams.size(), [&](std::size_t i) { return beams[i]; });
}

template <typename ScanT, typename MakeBeam>
void OccupancyGrid::insert_scan(const ScanT& scan, std::size_t beams, const MakeBeam& make_beam) {
  const Pose2D& pose = scan.sensor_pose;
  if (std::abs(pose.x_m) > kMaxSensorCoordinateM || std::abs(pose.y_m) > kMaxSensorCoordinateM) {
    throw std::invalid_argument("OccupancyGrid::insert: sensor position is more than 10000 km from the origin");
  }
  // Everything the scan can touch lies within this radius of the sensor; refuse before changing anything.
  const double reach_m = std::min(scan.range_max_m, usable_range_m(scan, options_.sensor)) *
                             (1.0 + range_sigma_per_m(scan, options_.sensor)) +
                         scan.sigma_range_m + 2.0 * options_.resolution_m;
  if (!(reach_m <= kMaxSensorCoordinateM)) {  // a σ of 1e300 m: no tile index could hold it
    throw std::invalid_argument("OccupancyGrid::insert: the scan reaches more than 10000 km (range σ or range)");
  }
  const double tile_m = options_.resolution_m * static_cast<double>(options_.tile_size_cells);
  check_growth(static_cast<std::int64_t>(std::floor((pose.x_m - reach_m) / tile_m)),
               static_cast<std::int64_t>(std::floor((pose.y_m - reach_m) / tile_m)),
               static_cast<std::int64_t>(std::floor((pose.x_m + reach_m) / tile_m)),
               static_cast<std::int64_t>(std::floor((pose.y_m + reach_m) / tile_m)));

  if (++stamp_ == 0) {
    // 2^32 scans later: forget the old stamps rather than mistake one for the current scan.
    for (auto& [index, tile] : tiles_) tile->stamp = 0;
    stamp_ = 1;
  }
  // A scan cut short by an exception (allocation) left bits behind: clear them, so this scan starts from none.
  for (std::size_t i = 0; i < scratch_used_; ++i) {
    std::fill(scratch_[i]->touched.begin(), scratch_[i]->touched.end(), 0);
  }
  scratch_used_ = 0;
  double cos_half = 1.0, sin_half = 0.0, half = -1.0;
  for (std::size_t i = 0; i < beams; ++i) {
    const std::optional<Beam> beam = make_beam(i);
    if (!beam) continue;
    if (beam->half_width_rad != half) {  // the same for every beam of a scan
      half = beam->half_width_rad;
      cos_half = std::cos(half);
      sin_half = std::sin(half);
    }
    walk(internal::prepare(*beam, options_.resolution_m, cos_half, sin_half));
  }
  apply_scan();
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

OccupancyGrid::ScanScratch& OccupancyGrid::scratch_for(Tile& tile) {
  if (tile.stamp != stamp_) {
    tile.stamp = stamp_;
    ++tile.revision;
    if (!tile.dirty) {
      tile.dirty = true;
      dirty_.push_back(tile.index);
    }
    if (scratch_used_ == scratch_.size()) {
      const auto n = static_cast<std::size_t>(options_.tile_size_cells * options_.tile_size_cells);
      scratch_.push_back(std::make_unique<ScanScratch>(n, options_.update_bayes, options_.update_ds));
    }
    tile.scratch = static_cast<std::uint32_t>(scratch_used_);
    scratch_[scratch_used_++]->tile = &tile;
  }
  return *scratch_[tile.scratch];
}

void OccupancyGrid::walk(const internal::PreparedBeam& b) {
  const bool bayes = options_.update_bayes;
  const bool ds = options_.update_ds;
  // The current tile along the beam: consecutive cells almost always share it.
  std::int64_t cur_x = std::numeric_limits<std::int64_t>::min();
  std::int64_t cur_y = 0;
  ScanScratch* s = nullptr;

  internal::for_each_beam_cell(b, [&](std::int64_t x, std::int64_t y, double d2, internal::CellClass cls) {
    const std::int64_t tx = x >> shift_;
    const std::int64_t ty = y >> shift_;
    if (tx != cur_x || ty != cur_y || s == nullptr) {
      s = &scratch_for(*tile_for_write(tx, ty));
      cur_x = tx;
      cur_y = ty;
    }
    const auto idx = static_cast<std::size_t>(((y & mask_) << shift_) | (x & mask_));
    std::uint64_t& word = s->touched[idx >> 6];
    const std::uint64_t bit = std::uint64_t{1} << (idx & 63);
    const bool first = (word & bit) == 0;
    word |= bit;
    const bool hit = cls == internal::CellClass::hit;

    // Range factor and angular weight only where they can differ from (0, 1): hits, and free cells just in front
    // of the return (the Gaussian's tail). Free space of a laser lies on its axis line: weight 1.
    double g = 0.0;
    double d = 0.0;
    double w = 1.0;
    if (b.has_return && (hit || d2 > b.tail_limit2)) {
      d = std::sqrt(d2);
      g = internal::range_factor(b, cls, x, y, d);
      if (hit || !b.free_on_axis_only) w = internal::angular_weight(b, x, y, d2);
    } else if (!b.free_on_axis_only && b.inv_two_sigma_a2 > 0.0) {
      w = internal::angular_weight(b, x, y, d2);
    }

    if (bayes) {
      float& increment = s->increment[idx];
      const auto v = static_cast<float>(w * (hit ? internal::bayes_hit_log_odds(b, g) : b.log_odds_miss));
      // The strongest hit if any beam hit the cell, else the strongest miss.
      if (first || ((v > 0.f || increment > 0.f) ? v > increment : v < increment)) increment = v;
    }
    if (ds) {
      ScanScratch::Masses& scan = s->masses[idx];
      const internal::CellMasses m =
          hit || g > 0.0 ? internal::ds_masses(b, g, d, w) : internal::CellMasses{0.0, w * b.k};
      if (first) {
        scan = {m.occupied, m.empty};
      } else {
        // Between beams the scan's masses are carried at the map's float precision; the last combination is kept
        // whole for the map. Beam masses are never certain (validated options), so a total conflict between
        // beams is only float rounding: keep what the scan had.
        double so = static_cast<float>(scan.o);
        double se = static_cast<float>(scan.e);
        double k = 0.0;
        combine(so, se, k, m.occupied, m.empty);
        scan = {so, se};
      }
    }
  });
}

void OccupancyGrid::apply_scan() {
  const bool bayes = options_.update_bayes;
  const bool ds = options_.update_ds;
  const auto lo = static_cast<float>(options_.log_odds_min);
  const auto hi = static_cast<float>(options_.log_odds_max);
  const double known_max = 1.0 - options_.ds_unknown_min;
  for (std::size_t t = 0; t < scratch_used_; ++t) {
    ScanScratch& s = *scratch_[t];
    Tile& tile = *s.tile;
    // In cell order: the tile's cells are read and written front to back, each once.
    for (std::size_t w = 0; w < s.touched.size(); ++w) {
      std::uint64_t bits = s.touched[w];
      if (bits == 0) continue;
      s.touched[w] = 0;
      for (; bits != 0; bits &= bits - 1) {
        const std::size_t i = w * 64 + static_cast<std::size_t>(std::countr_zero(bits));
        if (bayes) tile.log_odds[i] = std::clamp(tile.log_odds[i] + s.increment[i], lo, hi);
        if (ds) {
          // The scan's beams combined into the map cell with Dempster's rule, then discounted to m(Θ) >= the floor.
          DsCell& c = tile.ds[i];
          double o = c.o;
          double e = c.e;
          double k = 1.0;
          if (combine(o, e, k, s.masses[i].o, s.masses[i].e)) {
            if (o + e > known_max) {
              const double scale = known_max / (o + e);
              o *= scale;
              e *= scale;
            }
            c.o = static_cast<float>(o);
            c.e = static_cast<float>(e);
          } else {
            k = 1.0;  // total conflict: the cell keeps its masses
          }
          c.k = std::max(c.k, static_cast<float>(k));
        }
      }
    }
  }
  scratch_used_ = 0;
  if (scratch_.size() > kKeptScratch) scratch_.resize(kKeptScratch);
}

std::optional<GridGeometry> OccupancyGrid::bounds() const {
  if (!tile_bounds_) return std::nullopt;
  const auto& b = *tile_bounds_;
  return tiles_geometry({b[0], b[1]}, {b[2], b[3]});
}

GridGeometry OccupancyGrid::tiles_geometry(TileIndex first, TileIndex last) const {
  const std::int64_t t = options_.tile_size_cells;
  const double tile_m = options_.resolution_m * static_cast<double>(t);
  return GridGeometry({static_cast<double>(first.x) * tile_m, static_cast<double>(first.y) * tile_m},
                      options_.resolution_m, (last.x - first.x + 1) * t, (last.y - first.y + 1) * t);
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

double OccupancyGrid::CellReader::log_odds(CellIndex c) {
  const std::int64_t tx = c.x >> grid_.shift_;
  const std::int64_t ty = c.y >> grid_.shift_;
  if (!looked_ || tx != tx_ || ty != ty_) {
    tile_ = grid_.find_tile(tx, ty);
    tx_ = tx;
    ty_ = ty;
    looked_ = true;
  }
  return tile_ == nullptr
             ? 0.0
             : tile_->log_odds[static_cast<std::size_t>(((c.y & grid_.mask_) << grid_.shift_) | (c.x & grid_.mask_))];
}

double OccupancyGrid::probability(CellIndex c) const { return 1.0 - 1.0 / (1.0 + std::exp(log_odds(c))); }

OccupancyGrid::Masses OccupancyGrid::masses(CellIndex c) const {
  const auto [tile, i] = locate(c);
  if (tile == nullptr) return {0.0, 0.0, 1.0};
  const double o = tile->ds[i].o;
  const double e = tile->ds[i].e;
  return {o, e, std::max(0.0, 1.0 - o - e)};
}

double OccupancyGrid::belief(CellIndex c) const { return masses(c).occupied; }

double OccupancyGrid::plausibility(CellIndex c) const { return 1.0 - masses(c).empty; }

double OccupancyGrid::conflict(CellIndex c) const {
  const auto [tile, i] = locate(c);
  return tile == nullptr ? 0.0 : tile->ds[i].k;
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
  const std::size_t n = tile->log_odds.size();
  TileData data{std::vector<float>(n), std::vector<float>(n), std::vector<float>(n), std::vector<float>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    data.log_odds[i] = tile->log_odds[i];
    data.m_occupied[i] = tile->ds[i].o;
    data.m_empty[i] = tile->ds[i].e;
    data.conflict[i] = tile->ds[i].k;
  }
  return data;
}

void OccupancyGrid::set_tile(TileIndex t, TileData data) {
  const auto n = static_cast<std::size_t>(options_.tile_size_cells * options_.tile_size_cells);
  const auto fail = [](const std::string& what) { throw std::invalid_argument("OccupancyGrid::set_tile: " + what); };
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
  for (std::size_t i = 0; i < n; ++i) {
    tile->log_odds[i] = std::clamp(data.log_odds[i], lo, hi);
    tile->ds[i].o = data.m_occupied[i];
    tile->ds[i].e = data.m_empty[i];
    tile->ds[i].k = data.conflict[i];
  }
  ++tile->revision;
}

std::vector<TileIndex> OccupancyGrid::tiles() const {
  std::vector<TileIndex> out;
  out.reserve(tiles_.size());
  for (const auto& [index, tile] : tiles_) out.push_back(index);
  return out;
}

std::uint64_t OccupancyGrid::tile_revision(TileIndex t) const {
  const Tile* tile = find_tile(t.x, t.y);
  return tile ? tile->revision : 0;
}

std::vector<std::pair<TileIndex, std::uint64_t>> OccupancyGrid::tile_revisions() const {
  std::vector<std::pair<TileIndex, std::uint64_t>> out;
  out.reserve(tiles_.size());
  for (const auto& [index, tile] : tiles_) out.emplace_back(index, tile->revision);
  return out;
}

std::vector<float> OccupancyGrid::export_layer(Layer layer, const GridGeometry& region) const {
  if (region.width() > kMaxExportCells / region.height()) {
    throw std::invalid_argument("OccupancyGrid::export_layer: region has more than " + std::to_string(kMaxExportCells) +
                                " cells");
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
      const Eigen::Vector2d p = region.center_of({static_cast<std::int64_t>(col), static_cast<std::int64_t>(row)});
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
      out[row * w + col] =
          layer_value(*tile, static_cast<std::size_t>(((c.y & mask_) << shift_) | (c.x & mask_)), layer);
    }
  }
  return out;
}

std::vector<float> OccupancyGrid::export_tile_layers(TileIndex t) const {
  const auto n = static_cast<std::size_t>(options_.tile_size_cells * options_.tile_size_cells);
  constexpr float kUnknown = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> out(4 * n, kUnknown);
  const Tile* tile = find_tile(t.x, t.y);
  if (tile == nullptr) return out;
  // One pass over the tile writing all four layers (the shared-memory export copies every changed tile many times
  // a second): the same values as layer_value, which export_layer uses, without a branch on the layer per cell.
  float* const probability = out.data();
  float* const belief = probability + n;
  float* const plausibility = belief + n;
  float* const conflict = plausibility + n;
  for (std::size_t i = 0; i < n; ++i) {
    const float l = tile->log_odds[i];
    if (l != 0.f) probability[i] = 1.f - 1.f / (1.f + std::exp(l));
    const DsCell& c = tile->ds[i];
    if (c.o != 0.f || c.e != 0.f) {
      belief[i] = c.o;
      plausibility[i] = 1.f - c.e;
      conflict[i] = c.k;
    }
  }
  return out;
}

float OccupancyGrid::layer_value(const Tile& tile, std::size_t i, Layer layer) {
  const float o = tile.ds[i].o;
  const float e = tile.ds[i].e;
  const bool ds_unknown = o == 0.f && e == 0.f;
  switch (layer) {
    case Layer::bayes_probability:
      if (tile.log_odds[i] != 0.f) return 1.f - 1.f / (1.f + std::exp(tile.log_odds[i]));
      break;
    case Layer::ds_belief:
      if (!ds_unknown) return o;
      break;
    case Layer::ds_plausibility:
      if (!ds_unknown) return 1.f - e;
      break;
    case Layer::ds_conflict:
      if (!ds_unknown) return tile.ds[i].k;
      break;
  }
  return std::numeric_limits<float>::quiet_NaN();
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
