#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <shared_mutex>
#include <string>
#include <utility>
#include <vector>

#include "common/diagnostics.h"
#include "fusion/grid/beam_crossings.h"
#include "fusion/grid/laser_sonar_grids.h"
#include "fusion/grid/occupancy_grid.h"
#include "fusion/grid_lines/grid_line_extractor.h"
#include "server/service/world_port.h"
#include "server/service/writer_preferring_mutex.h"
#include "server/storage/store.h"
#include "server/world/grid_trim.h"
#include "server/world/plan_evidence.h"
#include "server/world/scan_observation.h"
#include "server/world/world_state.h"

namespace wm::service {

/// A cell is occupied at P > 0.65 (the map-quality definition of an occupied cell): log-odds above ln(0.65 / 0.35).
inline constexpr double kOccupiedLogOdds = 0.61903920840622351;

/// What the grid says of a point of an element (world::GridProbe, for the grid trim): backed when a cell within one
/// cell of it is occupied, contrary when those cells were seen and none is, unknown when none was seen. `cells` must
/// outlive the probe and be used under the grid's lock.
world::GridProbe grid_element_probe(fusion::OccupancyGrid::CellReader& cells, double resolution);

struct GridStoreOptions {
  fusion::GridOptions grid;  // a stored grid's resolution and tile size win over these
  /// Sonar judged by the laser before the fused grid takes it, the decision layer's thresholds.
  fusion::LaserSonarOptions laser_sonar;
  /// Changed tiles are written at most this often (the journal holds every scan; scans after the last flush are
  /// replayed at start).
  std::chrono::milliseconds flush_interval{1000};
  /// How the beams of laser scans are counted at the plan's edges (passed through, ended on).
  fusion::BeamCrossingOptions beam_crossings;
};

/// The map's occupancy grids (both models; fused, with laser-only and sonar-only grids beside it once sonar is seen:
/// fusion::LaserSonarGrids) with their lock, their flush to the store, and the laser beams counted at
/// the plan's edges (flushed with the tiles). One writer inserts scans in journal order; any thread reads. Readers
/// share a writer-preferring lock, so a stream of readers cannot starve the inserts.
class GridStore {
 public:
  /// Loads the grid and the edges' beam counts as last flushed. The scans journaled after the flush are the
  /// caller's to insert again (through_scan_seq() says from where). `diagnostics` hears of the beams it could not
  /// count. @throw storage::StorageError.
  GridStore(const GridStoreOptions& options, storage::Store& store, common::Diagnostics& diagnostics);
  GridStore(const GridStore&) = delete;
  GridStore& operator=(const GridStore&) = delete;

  // The writer's side.
  /// Inserts scan `seq` (laser and sonar may come out of order: the revision moves only through a scan whose
  /// predecessors are all in) and counts its beams at the edges of `state`'s objects near it. The scan is counted
  /// in the sequence even when the grid refuses it. @throw std::exception from the grid (a scan the HTTP boundary
  /// should have refused).
  void insert(const world::ScanObservation& scan, std::int64_t seq, const world::WorldState& state);
  /// Whether every scan up to the last inserted one is in (no gap left by an out-of-order insert).
  bool complete() const { return inserted_ahead_.empty(); }
  /// Writes the changed tiles and beam counts through last_scan_seq(), at most once per flush_interval unless
  /// `force`; nothing while a gap is open. @throw storage::StorageError (the next flush then writes everything).
  void flush(bool force);
  /// The last scan in the grid with all before it (writer thread).
  std::int64_t last_scan_seq() const { return last_scan_seq_; }
  /// The last scan the stored tiles hold (writer thread).
  std::int64_t flushed_scan_seq() const { return flushed_scan_seq_; }

  // Any thread.
  /// The journal sequence of the last scan in the grid (scans ever accepted); it never goes back across restarts.
  std::int64_t revision() const { return revision_.load(); }
  double resolution_m() const { return resolution_m_; }
  /// Runs `read(grid)` under the shared lock on the fused grid; `read` must not take it again.
  template <typename F>
  auto read(F&& read) const {
    std::shared_lock lock(mutex_);
    return read(grids_->fused());
  }
  /// Starts the laser-only and sonar-only grids empty, to be rebuilt from the journal through insert_side_only
  /// (start-up, before replay_journal_into_grid: the fused grid comes from its stored tiles).
  void start_side_grids();
  /// A journaled scan already in the stored fused grid, into the side grids only (writer thread, start-up).
  void insert_side_only(const world::ScanObservation& scan);
  GridSonarStatus sonar() const;
  /// Turns judging sonar by the laser on or off for the scans inserted from now on.
  void set_sonar_gate(bool on);
  std::optional<fusion::GridGeometry> bounds() const;
  /// A layer over `region`, with the revision read under the same lock (it counts exactly the scans the cells hold).
  GridLayerValues layer(fusion::GridLayer layer, const fusion::GridGeometry& region) const;
  GridTiles tiles() const;
  std::optional<GridTileValues> tile(fusion::GridLayer layer, std::int64_t tx, std::int64_t ty) const;
  std::optional<GridTileValues> tile_layers(std::int64_t tx, std::int64_t ty) const;
  /// The Bayes grid as probabilities, for the line extractor; nullopt when empty.
  std::optional<fusion::ProbabilityRaster> probability_raster() const;
  /// Where a scan changes the grid (its footprint up to its usable range, beam widths included), padded by pad_m.
  /// @throw std::exception from the scan geometry.
  Eigen::AlignedBox2d changed_region(const world::ScanObservation& scan, double pad_m) const;

  /// The grid's evidence on the plan edges of `state` in `region` (every edge when nullopt) that anything observed,
  /// with the beams counted at each edge and at each stretch seen through; `revision` is set to the grid revision
  /// it was read at. options.step_m is the grid's cell size.
  std::vector<world::EdgeEvidence> edge_evidence(const world::WorldState& state,
                                                 const std::optional<world::Box>& region,
                                                 world::PlanEvidenceOptions options, std::int64_t& revision) const;

 private:
  void count_edge_beams(const world::ScanObservation& scan, const world::WorldState& state);
  /// The counts of edge k of `object` where it stands now, nullptr when none (beams_mutex_ held).
  const fusion::SegmentBeams* edge_beams(const world::ObjectState& object, std::size_t k) const;

  const GridStoreOptions options_;
  storage::Store& store_;
  common::Diagnostics& diagnostics_;
  mutable WriterPreferringMutex mutex_;
  std::unique_ptr<fusion::LaserSonarGrids> grids_;  // changed by the writer only
  double resolution_m_ = 0;
  std::atomic<std::int64_t> revision_{0};
  // Writer only:
  std::set<std::int64_t> inserted_ahead_;  // scans inserted past a gap
  std::int64_t last_scan_seq_ = 0;
  std::int64_t flushed_scan_seq_ = 0;
  bool flush_all_ = false;  // a flush failed: its dirty lists are gone, the next one writes everything
  std::chrono::steady_clock::time_point last_flush_ = std::chrono::steady_clock::now();

  mutable std::mutex beams_mutex_;
  std::map<std::pair<std::string, std::size_t>, fusion::SegmentBeams> edge_beams_;  // by (object id, edge)
  std::set<std::pair<std::string, std::size_t>> beams_dirty_;                       // since the last flush
};

}  // namespace wm::service
