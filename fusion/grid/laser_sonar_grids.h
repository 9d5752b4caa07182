#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "fusion/grid/occupancy_grid.h"
#include "fusion/grid/sonar_gate.h"

namespace wm::fusion {

/// What the Dempster–Shafer grid answers for a cell (docs/fusion.md §8): the support Bel(O) = m(O) and the
/// plausibility Pl(O) = 1 − m(E) bound the evidence for "occupied"; a decision needs the interval on one side.
///  - conflict:  the cell's conflict (the largest K of its combinations) >= conflict_min: sources disagreed there;
///  - occupied:  Bel(O) >= occupied_belief_min;
///  - free:      Pl(O) <= free_plausibility_max (m(E) >= 1 − that);
///  - undecided: seen, but the interval straddles both (not enough evidence either way).
struct DsDecisionOptions {
  double occupied_belief_min = 0.6;    // (0, 1]
  double free_plausibility_max = 0.4;  // [0, 1)
  double conflict_min = 0.6;           // (0, 1]; above 1 never
};
/// @throw std::invalid_argument naming the first field outside its range.
void validate(const DsDecisionOptions& options);

enum class DsDecision { free, occupied, undecided, conflict };
DsDecision ds_decision(const OccupancyGrid::Masses& masses, double conflict, const DsDecisionOptions& options);
/// The decision as a layer value: free 0, undecided 0.5, conflict 0.75, occupied 1 (a PGM shows free white, occupied
/// black, the others grey).
float ds_decision_value(DsDecision decision);

/// Every layer the grids serve. The first four are the fused grid's own (OccupancyGrid::Layer).
enum class GridLayer {
  bayes,                 // fused (laser + gated sonar) Bayes probability
  ds_belief,             // fused DS Bel(O)
  ds_plausibility,       // fused DS Pl(O)
  ds_conflict,           // fused DS conflict (scan against map)
  ds_decision,           // fused DS decision (ds_decision_value)
  laser_bayes,           // laser-only Bayes probability
  laser_ds_decision,     // laser-only DS decision
  sonar_bayes,           // sonar-only Bayes probability (every reading, as it came: ungated)
  laser_sonar_conflict,  // Dempster's K between the laser-only and the sonar-only masses of the cell
};
inline constexpr std::array<std::string_view, 9> kGridLayerNames = {
    "bayes",       "ds_belief",         "ds_plausibility", "ds_conflict",         "ds_decision",
    "laser_bayes", "laser_ds_decision", "sonar_bayes",     "laser_sonar_conflict"};
std::string_view to_string(GridLayer layer);
/// The fused grid's own layer a GridLayer is (the first four), nullopt for the derived ones.
std::optional<OccupancyGrid::Layer> stored_layer(GridLayer layer);
/// nullopt for a name not in kGridLayerNames.
std::optional<GridLayer> grid_layer_named(std::string_view name);

struct LaserSonarOptions {
  bool gate_sonar = true;  // judge sonar by the laser before the fused grid takes it; false: fused as it comes
  std::size_t recent_laser_scans = 8;  // the latest laser scans whose returns back a sonar return, [0, 64]
  SonarGateOptions gate;
  DsDecisionOptions decision;
};
/// @throw std::invalid_argument naming the first field outside its range.
void validate(const LaserSonarOptions& options);

/// What the gate did, summed over every sonar scan (SonarVerdict counts).
struct SonarGateCounts {
  std::uint64_t scans = 0;
  std::uint64_t kept = 0, unjudged = 0, phantom = 0, clipped = 0, ignored = 0;
};

/// The grids of a map that has laser and sonar: the fused grid (laser and sonar, sonar judged by the laser first),
/// with a laser-only and a sonar-only grid beside it. The side grids cost nothing until the first sonar scan: until
/// then the fused grid is the laser-only grid, and at the first sonar scan it is copied to become it.
/// Not thread-safe for writers; const members may run concurrently with each other.
class LaserSonarGrids {
 public:
  /// @throw std::invalid_argument for invalid options.
  LaserSonarGrids(const GridOptions& grid, const LaserSonarOptions& options);
  LaserSonarGrids(const LaserSonarGrids& other);
  LaserSonarGrids& operator=(const LaserSonarGrids& other);
  LaserSonarGrids(LaserSonarGrids&&) noexcept = default;
  LaserSonarGrids& operator=(LaserSonarGrids&&) noexcept = default;
  ~LaserSonarGrids() = default;

  /// Into the fused grid and the laser-only one. @throw as OccupancyGrid::insert.
  void insert(const LaserScan& scan);
  /// Into the sonar-only grid as it came, into the fused grid as the gate left it. @throw as OccupancyGrid::insert.
  SonarGateResult insert(const SonarScan& scan);
  /// Only into the side grids (rebuilding them from a journal while the fused grid comes from its stored tiles).
  void insert_side_only(const LaserScan& scan);
  void insert_side_only(const SonarScan& scan);
  /// Starts the side grids as if sonar had been seen: empty laser-only and sonar-only grids (then filled with
  /// insert_side_only), not a copy of the fused grid.
  void start_side_grids();

  OccupancyGrid& fused() { return fused_; }
  const OccupancyGrid& fused() const { return fused_; }
  /// The laser-only grid (the fused one while no sonar was seen).
  const OccupancyGrid& laser_only() const { return laser_ ? *laser_ : fused_; }
  /// nullptr while no sonar was seen.
  const OccupancyGrid* sonar_only() const { return sonar_.get(); }
  bool has_sonar() const { return sonar_ != nullptr; }
  const SonarGateCounts& gate_counts() const { return counts_; }
  const LaserSonarOptions& options() const { return options_; }
  /// Judges the sonar scans inserted from now on by the laser, or not.
  void set_gate_sonar(bool on) { options_.gate_sonar = on; }

  /// A layer over a region as OccupancyGrid::export_layer (NaN unknown; sonar layers all NaN without sonar).
  /// @throw std::invalid_argument when the region has more than OccupancyGrid::kMaxExportCells cells.
  std::vector<float> export_layer(GridLayer layer, const GridGeometry& region) const;
  /// Names the content of tile t in `layer` (changes whenever a grid the layer reads changes there); 0 when the
  /// fused grid has no tile t (every layer has a tile, NaN where it knows nothing, wherever the fused grid has one).
  std::uint64_t tile_revision(GridLayer layer, TileIndex t) const;

 private:
  void start_sides(bool copy_fused);

  GridOptions grid_options_;
  LaserSonarOptions options_;
  OccupancyGrid fused_;
  std::unique_ptr<OccupancyGrid> laser_;
  std::unique_ptr<OccupancyGrid> sonar_;
  SonarGateCounts counts_;
  std::vector<std::vector<Eigen::Vector2d>> recent_;  // return points of the latest laser scans, oldest first
  void remember_returns(const LaserScan& scan);
  /// The gate's verdicts (every reading kept as it came when the gate is off).
  SonarGateResult judge(const SonarScan& scan) const;
  void count(const SonarGateResult& gated);
};

}  // namespace wm::fusion
