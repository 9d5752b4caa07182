#pragma once

#include <array>
#include <compare>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "fusion/grid/grid_geometry.h"
#include "fusion/grid/scan.h"
#include "fusion/grid/sensor_model.h"

namespace wm::fusion {
namespace internal {
struct PreparedBeam;
}  // namespace internal

struct GridOptions {
  double resolution_m = 0.05;         // cell size [m], [0.001, 100]
  std::int64_t tile_size_cells = 64;  // tile side [cells], a power of two in [4, 1024]
  double log_odds_min = -2.0;         // Bayes clamping (OctoMap: p 0.1192), < 0
  double log_odds_max = 3.5;          // Bayes clamping (OctoMap: p 0.971), > 0
  /// DS counterpart of the clamping, [0, 1): after each combination into the map, a cell whose m(Θ) fell below this
  /// is discounted back to it (m(O), m(E) scaled by (1 − this)/(m(O) + m(E))). Without it Dempster's rule makes a
  /// cell seen free a few dozen times (m(E) → 1) deaf to every later hit — a door that closes, or a wall cell a
  /// grazing ray once crossed. 0 disables it.
  double ds_unknown_min = 0.05;
  SensorModelOptions sensor;
  /// Which models insert() updates; a disabled one keeps its layers unknown. Both by default; one alone is for
  /// measuring each model's cost (bench/grid_bench) or for a server that serves only one. At least one.
  bool update_bayes = true;
  bool update_ds = true;
};

/// Bayes (Elfes) log-odds grid AND Dempster–Shafer evidential grid over the same cells, updated together by
/// insert() with the inverse sensor models of sensor_model.h. The world origin is the lower-left corner of cell
/// (0, 0); cells may have negative indices and storage grows in every direction in tiles created on first touch
/// (nothing is ever copied to grow). Unknown cells: log-odds 0, m(Θ) = 1.
///
/// Per scan, every cell is updated at most once per model, however many beams reach it (near the sensor dense
/// beams overlap). The beams' evidence is gathered beside the map, per touched tile (a bitmap of the cells reached and
/// the scan's value for each), and applied to the map when the scan's last beam has been walked:
///  - Bayes: the strongest hit wins if any beam hit the cell (a hit beats a miss from another beam of the same
///    scan), else the strongest miss; l = clamp(l_before + increment, log_odds_min, log_odds_max).
///  - DS: the beams' masses for the cell are combined with Dempster's rule, the result is combined into the map
///    cell as it was before the scan with Dempster's rule (and discounted to m(Θ) >= ds_unknown_min); that
///    combination's conflict K feeds the conflict layer.
/// Cost: one pass over the beams' cells into the scratch, then one pass over each touched tile's reached cells in
/// memory order; the map holds only values (4 bytes a cell for Bayes, 12 for DS). No allocation per beam (the
/// scratch is reused from scan to scan), tiles found through the current tile and a small direct-mapped cache (a
/// std::map lookup only when a beam enters a tile not seen lately).
/// Invariant: the touched tiles span at most GridGeometry::kMaxSizeCells cells per side, so bounds() is valid.
/// Not thread-safe for writers; const members may run concurrently with each other.
class OccupancyGrid {
  struct Tile;

 public:
  /// @throw std::invalid_argument for options outside the ranges documented in GridOptions / SensorModelOptions.
  explicit OccupancyGrid(const GridOptions& options);
  ~OccupancyGrid();
  OccupancyGrid(const OccupancyGrid& other);  // deep copy (e.g. for read-only snapshots)
  OccupancyGrid& operator=(const OccupancyGrid& other);
  OccupancyGrid(OccupancyGrid&&) noexcept;
  OccupancyGrid& operator=(OccupancyGrid&&) noexcept;

  /// Adds one laser scan (whole or not at all).
  /// @throw std::invalid_argument when validate(scan) fails, the sensor is more than 10'000 km from the origin,
  ///        or the scan would grow the grid beyond GridGeometry::kMaxSizeCells cells per side.
  void insert(const LaserScan& scan);
  /// Adds one sonar ring; same rules and exceptions as the laser overload.
  void insert(const SonarScan& scan);
  /// Adds a sonar ring whose beams were resolved beforehand (sonar_beam, then changed: the sonar gate drops and
  /// shortens beams); beams[i] nullopt skips reading i. Same rules and exceptions as insert(scan), and
  /// @throw std::invalid_argument when beams.size() differs from the scan's, or a beam is not finite, starts
  ///        elsewhere than the sensor or reaches farther than the scan's own beams could.
  void insert(const SonarScan& scan, const std::vector<std::optional<Beam>>& beams);

  double resolution_m() const { return options_.resolution_m; }
  const GridOptions& options() const { return options_; }
  /// Smallest geometry covering every touched tile (nullopt when empty).
  std::optional<GridGeometry> bounds() const;

  /// Bayes log-odds of cell c; 0 for unknown cells.
  double log_odds(CellIndex c) const;
  /// Bayes occupancy probability 1 − 1/(1 + exp(l)); 0.5 for unknown cells.
  double probability(CellIndex c) const;

  /// Reads log-odds through a cache of the last tile it looked in, so that many reads close together (the samples
  /// along a line, a cell's neighbours) cost one tile lookup per tile rather than one per cell. Refers to the grid:
  /// valid while nothing changes the grid's tiles (the caller keeps writers out). Not shared between threads.
  class CellReader {
   public:
    explicit CellReader(const OccupancyGrid& grid) : grid_(grid) {}
    /// The same as OccupancyGrid::log_odds(c).
    double log_odds(CellIndex c);

   private:
    const OccupancyGrid& grid_;
    std::int64_t tx_ = 0;
    std::int64_t ty_ = 0;
    const Tile* tile_ = nullptr;
    bool looked_ = false;
  };

  /// Masses on the frame {O, E}; unknown is m(Θ) = 1 − occupied − empty.
  struct Masses {
    double occupied;
    double empty;
    double unknown;
  };
  /// DS masses of cell c; unknown = 1 for untouched cells.
  Masses masses(CellIndex c) const;
  /// Bel(O) = m(O).
  double belief(CellIndex c) const;
  /// Pl(O) = 1 − m(E).
  double plausibility(CellIndex c) const;
  /// The conflict layer: the largest K of the scan-into-map Dempster combinations this cell has seen (max over
  /// scans, so one strong disagreement, e.g. a person walking through mapped free space, stays visible);
  /// 1 when a combination was in total conflict; 0 for unknown cells.
  double conflict(CellIndex c) const;

  /// Tiles changed by insert() since the last call (then cleared), sorted. set_tile() does not mark tiles.
  std::vector<TileIndex> take_dirty_tiles();

  /// One tile's cells, row-major from its lower-left cell (tile_size² each). float storage: DS masses and
  /// log-odds need no more, and it halves the memory traffic of the update.
  struct TileData {
    std::vector<float> log_odds;
    std::vector<float> m_occupied;
    std::vector<float> m_empty;
    std::vector<float> conflict;
  };
  /// Raw access for persistence; nullopt when the tile was never touched.
  std::optional<TileData> tile(TileIndex t) const;
  /// Restores a tile (exactly; log-odds outside the clamping range are clamped).
  /// @throw std::invalid_argument when a layer's size is not tile_size², a value is not finite, a mass or the
  ///        conflict is outside [0, 1], m_occupied + m_empty > 1 (beyond float rounding), or the tile would grow
  ///        the grid beyond kMaxSizeCells per side.
  void set_tile(TileIndex t, TileData data);
  /// Every touched tile, sorted.
  std::vector<TileIndex> tiles() const;
  /// The cells of the tiles from `first` to `last` (inclusive, x and y): cell (0, 0) has its lower-left corner at the
  /// world origin, so tile (tx, ty) starts at (tx·T·resolution, ty·T·resolution).
  GridGeometry tiles_geometry(TileIndex first, TileIndex last) const;
  /// How many inserts (and restores) changed tile t; 0 when never touched. A tile's cells stay the same while this
  /// number does, so it can name their content (an HTTP ETag, a reader's check).
  std::uint64_t tile_revision(TileIndex t) const;
  /// Every touched tile with its revision, sorted.
  std::vector<std::pair<TileIndex, std::uint64_t>> tile_revisions() const;
  std::int64_t tile_size_cells() const { return options_.tile_size_cells; }

  enum class Layer { bayes_probability, ds_belief, ds_plausibility, ds_conflict };
  /// Largest region export_layer() produces [cells].
  static constexpr std::int64_t kMaxExportCells = std::int64_t{1} << 26;
  /// Dense export of a layer over a region, row-major from the region's lower-left cell; each region cell takes
  /// the value of the grid cell containing its centre (exact when the region is aligned with the grid).
  /// Unknown cells (Bayes: log-odds 0; DS: m(Θ) = 1) are NaN.
  /// @throw std::invalid_argument when the region has more than kMaxExportCells cells.
  std::vector<float> export_layer(Layer layer, const GridGeometry& region) const;
  /// Every layer of tile t, in Layer order, tile_size² values each (row-major from the tile's lower-left cell, NaN
  /// unknown): the same values as export_layer over tiles_geometry(t, t), read straight from the tile.
  std::vector<float> export_tile_layers(TileIndex t) const;

 private:
  struct DsCell;
  struct ScanScratch;
  struct CacheEntry {
    std::int64_t x = 0;
    std::int64_t y = 0;
    Tile* tile = nullptr;
  };

  template <typename ScanT, typename MakeBeam>
  void insert_scan(const ScanT& scan, std::size_t beams, const MakeBeam& make_beam);
  void walk(const internal::PreparedBeam& beam);
  /// The scratch of `tile` in this scan; the first call of a scan for a tile takes a free one (and marks the tile
  /// changed: revision, dirty list).
  ScanScratch& scratch_for(Tile& tile);
  /// Writes the scan's evidence into the map, once per reached cell, and clears the scratch for the next scan.
  void apply_scan();
  void check_growth(std::int64_t tx0, std::int64_t ty0, std::int64_t tx1, std::int64_t ty1) const;
  Tile* tile_for_write(std::int64_t tx, std::int64_t ty);
  const Tile* find_tile(std::int64_t tx, std::int64_t ty) const;
  /// Cell i of `tile` in `layer`, NaN when unknown there.
  static float layer_value(const Tile& tile, std::size_t i, Layer layer);
  /// The tile holding c and c's index in it, or nullptr.
  std::pair<const Tile*, std::size_t> locate(CellIndex c) const;

  GridOptions options_;
  int shift_ = 6;
  std::int64_t mask_ = 63;
  std::map<TileIndex, std::unique_ptr<Tile>> tiles_;
  std::optional<std::array<std::int64_t, 4>> tile_bounds_;  // min x, min y, max x, max y
  std::array<CacheEntry, 64> cache_{};                      // direct-mapped: slot (x & 7) | (y & 7) << 3
  std::uint32_t stamp_ = 0;
  std::vector<TileIndex> dirty_;
  std::vector<std::unique_ptr<ScanScratch>> scratch_;  // the first scratch_used_ belong to the scan being inserted
  std::size_t scratch_used_ = 0;
};

/// Dempster's rule on the frame {O, E} (docs/fusion.md §1): K = a_O·b_E + a_E·b_O,
/// m(O) = (a_O·b_O + a_O·b_Θ + a_Θ·b_O)/(1 − K), m(E) likewise, m(Θ) = a_Θ·b_Θ/(1 − K).
/// Total conflict (K = 1, within 1e-12) returns nullopt masses (the caller keeps the old cell and records K = 1).
struct DempsterResult {
  std::optional<OccupancyGrid::Masses> masses;
  double conflict;
};
/// @throw std::invalid_argument when a mass is not finite, outside [0, 1], or a triple does not sum to 1 (±1e-6).
DempsterResult dempster_combine(const OccupancyGrid::Masses& a, const OccupancyGrid::Masses& b);

}  // namespace wm::fusion
