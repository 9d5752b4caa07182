#include "server/service/grid_store.h"

#include <algorithm>
#include <cmath>
#include <type_traits>
#include <variant>

#include "fusion/grid/scan_geometry.h"
#include "fusion/grid/sensor_model.h"
#include "fusion/grid_lines/raster.h"

namespace wm::service {
namespace {

/// Beam counts stay with an edge while it stands where they were counted (within a centimetre).
bool same_place(const fusion::SegmentBeams& counted, const fusion::LineSegment& edge) {
  constexpr double kToleranceM = 0.01;
  return (counted.p0 - edge.p0()).norm() <= kToleranceM && (counted.p1 - edge.p1()).norm() <= kToleranceM;
}

/// What the grid says of a point of a drawn edge (world::EdgeProbe). Occupied is P > 0.65, the map-quality
/// definition; free is P < 0.25, which the laser's miss evidence (p_miss 0.4) reaches after three scans saw
/// through the cell, so one stray beam or a grazing ray does not make a wall "seen through".
/// The probe looks across the edge only (cells at up to one cell along its normal, in half-cell steps): along it, a
/// standing wall's last cell would otherwise back the first cell of a door beside it, and every opening would be
/// found a cell short at each end. Backed: one of those cells occupied. Displaced: none, but a cell occupied within
/// 3 cells across (the surface stands a little off its drawing, or the pose error blurs it): no evidence either way
/// of a missing wall. Seen through: all of them seen and free, and nothing occupied across. Unknown otherwise.
world::EdgeProbe grid_edge_probe(fusion::OccupancyGrid::CellReader& cells, double resolution) {
  const double occupied = kOccupiedLogOdds;
  const double free = std::log(0.25 / 0.75);
  return [&cells, resolution, occupied, free](const Eigen::Vector2d& point, const Eigen::Vector2d& normal) {
    const auto log_odds = [&](double cells_across) {
      const Eigen::Vector2d p = point + cells_across * resolution * normal;
      return cells.log_odds(fusion::cell_at(p, resolution));
    };
    bool all_free = true;
    for (const double t : {0.0, -0.5, 0.5, -1.0, 1.0}) {
      const double l = log_odds(t);
      if (l > occupied) return world::EdgeSample::backed;
      all_free = all_free && l < free;
    }
    for (const double t : {1.5, 2.0, 2.5, 3.0})
      if (log_odds(t) > occupied || log_odds(-t) > occupied) return world::EdgeSample::displaced;
    return all_free ? world::EdgeSample::seen_through : world::EdgeSample::unknown;
  };
}

}  // namespace

world::GridProbe grid_element_probe(fusion::OccupancyGrid::CellReader& cells, double resolution) {
  return [&cells, resolution](const Eigen::Vector2d& point) {
    const auto [cx, cy] = fusion::cell_at(point, resolution);
    bool seen_any = false;
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const double l = cells.log_odds({cx + dx, cy + dy});
        if (l > kOccupiedLogOdds) return world::GridEvidence::backed;
        seen_any = seen_any || l != 0.0;
      }
    return seen_any ? world::GridEvidence::contrary : world::GridEvidence::unknown;
  };
}

GridStore::GridStore(const GridStoreOptions& options, storage::Store& store, common::Diagnostics& diagnostics)
    : options_(options), store_(store), diagnostics_(diagnostics) {
  auto grid_options = options_.grid;
  const auto stored = store_.load_grid();
  if (stored) {
    grid_options.resolution_m = stored->resolution_m;
    grid_options.tile_size_cells = stored->tile_size_cells;
  }
  grids_ = std::make_unique<fusion::LaserSonarGrids>(grid_options, options_.laser_sonar);
  resolution_m_ = grids_->fused().resolution_m();
  if (stored) {
    for (const auto& [index, data] : stored->tiles) grids_->fused().set_tile(index, data);
    flushed_scan_seq_ = last_scan_seq_ = stored->through_scan_seq;
    revision_ = last_scan_seq_;
  }
  for (auto& row : store_.load_edge_beams())
    edge_beams_[{row.object_id, static_cast<std::size_t>(row.edge)}] = std::move(row.beams);
}

void GridStore::insert(const world::ScanObservation& scan, std::int64_t seq, const world::WorldState& state) {
  std::exception_ptr refused;
  {
    std::unique_lock lock(mutex_);
    try {
      std::visit([this](const auto& s) { grids_->insert(s); }, scan.scan);
    } catch (...) {
      refused = std::current_exception();
    }
    inserted_ahead_.insert(seq);
    while (!inserted_ahead_.empty() && *inserted_ahead_.begin() == last_scan_seq_ + 1) {
      last_scan_seq_ = *inserted_ahead_.begin();
      inserted_ahead_.erase(inserted_ahead_.begin());
    }
    // Under the lock: a reader that reads it inside read() sees the revision of what it reads.
    revision_ = last_scan_seq_;
  }
  count_edge_beams(scan, state);  // before the next flush, which writes them through the same scan as the tiles
  if (refused) std::rethrow_exception(refused);
}

void GridStore::count_edge_beams(const world::ScanObservation& scan, const world::WorldState& state) {
  const auto* laser = std::get_if<fusion::LaserScan>(&scan.scan);
  if (!laser || state.objects.empty()) return;
  try {
    const double reach = fusion::usable_range_m(*laser, options_.grid.sensor);
    const auto box = changed_region(scan, options_.beam_crossings.margin_m);
    const auto near = state.objects.edges_near({box.min().x(), box.min().y(), box.max().x(), box.max().y()});
    if (near.empty()) return;
    std::vector<fusion::SegmentBeams> segments;
    std::vector<std::pair<std::string, std::size_t>> keys;
    std::lock_guard lock(beams_mutex_);
    for (const auto& [i, k] : near) {
      const auto& object = state.objects[i];
      const auto edge = object.body.world_edge(k, Eigen::Matrix2d::Zero());
      std::pair<std::string, std::size_t> key{object.plan->id, k};
      auto found = edge_beams_.find(key);
      if (found != edge_beams_.end() && same_place(found->second, edge)) {
        segments.push_back(std::move(found->second));
      } else {
        // The edge is new or has moved (a new plan, placement or pose): its counts start again.
        const auto bins = fusion::beam_bins(edge.length_m(), options_.beam_crossings);
        segments.push_back(
            {edge.p0(), edge.p1(), std::vector<std::uint32_t>(bins, 0), std::vector<std::uint32_t>(bins, 0)});
      }
      keys.push_back(std::move(key));
    }
    fusion::count_beam_crossings(*laser, reach, options_.beam_crossings, segments, scan.pose_cov);
    for (std::size_t n = 0; n < keys.size(); ++n) {
      beams_dirty_.insert(keys[n]);
      edge_beams_[keys[n]] = std::move(segments[n]);
    }
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::warning, "grid",
                        std::string("beams of a scan not counted at the plan's edges: ") + e.what());
  }
}

const fusion::SegmentBeams* GridStore::edge_beams(const world::ObjectState& object, std::size_t k) const {
  const auto found = edge_beams_.find({object.plan->id, k});
  if (found == edge_beams_.end()) return nullptr;
  return same_place(found->second, object.body.world_edge(k, Eigen::Matrix2d::Zero())) ? &found->second : nullptr;
}

void GridStore::flush(bool force) {
  if (!complete()) return;  // the journal is replayed past the gap at start
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - last_flush_ < options_.flush_interval) return;
  if (last_scan_seq_ == flushed_scan_seq_ && !force) return;
  storage::Store::StoredGrid changed;
  changed.through_scan_seq = last_scan_seq_;
  {
    std::unique_lock lock(mutex_);  // take_dirty_tiles changes the grid's bookkeeping
    auto& grid = grids_->fused();
    changed.resolution_m = grid.resolution_m();
    changed.tile_size_cells = grid.tile_size_cells();
    auto tiles = grid.take_dirty_tiles();
    if (flush_all_) tiles = grid.tiles();
    for (const auto& index : tiles)
      if (auto data = grid.tile(index)) changed.tiles.emplace_back(index, std::move(*data));
  }
  {
    std::set<std::pair<std::string, std::size_t>> flushed;
    std::lock_guard lock(beams_mutex_);
    flushed.swap(beams_dirty_);
    if (flush_all_)
      for (const auto& [key, counts] : edge_beams_) flushed.insert(key);
    for (const auto& key : flushed)
      if (const auto found = edge_beams_.find(key); found != edge_beams_.end())
        changed.edge_beams.push_back({key.first, static_cast<std::int64_t>(key.second), found->second});
  }
  if (changed.tiles.empty() && changed.edge_beams.empty() && last_scan_seq_ == flushed_scan_seq_) return;
  try {
    store_.flush_grid(changed);
  } catch (...) {
    flush_all_ = true;
    throw;
  }
  flush_all_ = false;
  flushed_scan_seq_ = last_scan_seq_;
  last_flush_ = now;
}

std::optional<fusion::GridGeometry> GridStore::bounds() const {
  return read([](const fusion::OccupancyGrid& grid) { return grid.bounds(); });
}

GridLayerValues GridStore::layer(fusion::GridLayer layer, const fusion::GridGeometry& region) const {
  std::shared_lock lock(mutex_);
  return GridLayerValues{grids_->export_layer(layer, region), revision_.load()};
}

void GridStore::start_side_grids() {
  std::unique_lock lock(mutex_);
  grids_->start_side_grids();
}

void GridStore::insert_side_only(const world::ScanObservation& scan) {
  std::unique_lock lock(mutex_);
  std::visit([this](const auto& s) { grids_->insert_side_only(s); }, scan.scan);
}

void GridStore::set_sonar_gate(bool on) {
  std::unique_lock lock(mutex_);
  grids_->set_gate_sonar(on);
}

GridSonarStatus GridStore::sonar() const {
  std::shared_lock lock(mutex_);
  return {grids_->has_sonar(), grids_->options().gate_sonar, grids_->gate_counts()};
}

GridTiles GridStore::tiles() const {
  return read([&](const fusion::OccupancyGrid& grid) {
    GridTiles result{grid.tile_size_cells(), grid.resolution_m(), revision_.load(), {}};
    for (const auto& [index, revision] : grid.tile_revisions()) result.tiles.push_back({index.x, index.y, revision});
    return result;
  });
}

std::optional<GridTileValues> GridStore::tile(fusion::GridLayer layer, std::int64_t tx, std::int64_t ty) const {
  std::shared_lock lock(mutex_);
  const auto revision = grids_->tile_revision(layer, {tx, ty});
  if (revision == 0) return std::nullopt;
  const auto& grid = grids_->fused();
  return GridTileValues{grids_->export_layer(layer, grid.tiles_geometry({tx, ty}, {tx, ty})), revision};
}

std::optional<GridTileValues> GridStore::tile_layers(std::int64_t tx, std::int64_t ty) const {
  return read([&](const fusion::OccupancyGrid& grid) -> std::optional<GridTileValues> {
    const auto revision = grid.tile_revision({tx, ty});
    if (revision == 0) return std::nullopt;
    return GridTileValues{grid.export_tile_layers({tx, ty}), revision};
  });
}

std::optional<fusion::ProbabilityRaster> GridStore::probability_raster() const {
  return read([](const fusion::OccupancyGrid& grid) { return fusion::probability_raster(grid); });
}

Eigen::AlignedBox2d GridStore::changed_region(const world::ScanObservation& scan, double pad_m) const {
  const auto& sensor = options_.grid.sensor;
  // The grid changed around the pose and along every beam, up to its return or the grid's usable range; wide
  // beams (a sonar cone, the laser's 2°) reach beyond their axis.
  return std::visit(
      [&](const auto& s) {
        const double reach = std::min(s.range_max_m, fusion::usable_range_m(s, sensor));
        double half_width = sensor.laser_beam_width_rad / 2;
        if constexpr (std::is_same_v<std::decay_t<decltype(s)>, fusion::SonarScan>) half_width = s.beam_width_rad / 2;
        return fusion::scan_footprint(s, reach, half_width, pad_m);
      },
      scan.scan);
}

std::vector<world::EdgeEvidence> GridStore::edge_evidence(const world::WorldState& state,
                                                          const std::optional<world::Box>& region,
                                                          world::PlanEvidenceOptions options,
                                                          std::int64_t& revision) const {
  std::vector<world::EdgeEvidence> found;
  const double bin = options_.beam_crossings.bin_m;
  // The beams counted in the bins of an edge that [s0, s1) touches.
  const auto tally = [bin](const fusion::SegmentBeams& counted, double s0, double s1) {
    const auto first = static_cast<std::size_t>(std::max(0.0, std::floor(s0 / bin)));
    const auto last = std::min(counted.through.size(), static_cast<std::size_t>(std::max(0.0, std::ceil(s1 / bin))));
    world::BeamTally beams;
    for (std::size_t b = first; b < last; ++b) {
      beams.through += counted.through[b];
      beams.ended += counted.ended[b];
    }
    return beams;
  };
  // The grid's lock, then the beams': nothing takes them the other way round.
  std::shared_lock lock(mutex_);
  std::lock_guard beams_lock(beams_mutex_);
  fusion::OccupancyGrid::CellReader cells(grids_->fused());
  options.step_m = resolution_m_;
  const auto probe = grid_edge_probe(cells, resolution_m_);
  const world::EdgeCrossings crossings = [&](std::size_t object, std::size_t edge, double s0, double s1) {
    const auto* counted = edge_beams(state.objects[object], edge);
    return counted ? tally(*counted, s0, s1) : world::BeamTally{};
  };
  found = region ? world::plan_evidence(state, *region, probe, options, crossings)
                 : world::plan_evidence(state, probe, options, crossings);
  revision = revision_.load();
  // Edges nothing has seen say nothing.
  std::erase_if(found, [](const world::EdgeEvidence& e) { return e.observed <= 0; });
  // The beams counted at each edge, and at each stretch seen through (the bins it covers).
  for (auto& e : found) {
    const auto* counted = edge_beams(state.objects[e.object], e.edge);
    if (!counted) continue;
    const auto all = tally(*counted, 0, bin * static_cast<double>(counted->through.size()));
    e.beams_through = all.through;
    e.beams_ended = all.ended;
    for (auto& stretch : e.seen_through_stretches) {
      const auto beams = tally(*counted, stretch.s0_m, stretch.s1_m);
      stretch.beams_through = beams.through;
      stretch.beams_ended = beams.ended;
    }
  }
  return found;
}

}  // namespace wm::service
