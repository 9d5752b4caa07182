#include <cstdint>

#include "server/storage/store.h"
#include "server/storage/store_internal.h"

// The grid as flushed: its tiles and the beams counted at each plan edge, written in one transaction.
namespace wm::storage {

using internal::run;

namespace {

std::vector<float> read_floats(const Statement& s, int column, std::size_t expected) {
  const auto* data = static_cast<const float*>(s.column_blob(column));
  const auto bytes = s.column_bytes(column);
  if (bytes != expected * sizeof(float)) throw StorageError("corrupt grid tile in database");
  return std::vector<float>(data, data + expected);
}

void bind_floats(Statement& s, int index, const std::vector<float>& values) {
  s.bind_blob(index, values.data(), sizeof(float) * values.size());
}

}  // namespace

std::optional<Store::StoredGrid> Store::load_grid() {
  std::lock_guard lock(writer_mutex_);
  StoredGrid grid;
  {
    Statement s(*writer_, "SELECT resolution, tile_size, through_scan_seq FROM grid_meta WHERE id = 1");
    if (!s.step()) return std::nullopt;
    grid.resolution_m = s.column_double(0);
    grid.tile_size_cells = s.column_int(1);
    grid.through_scan_seq = s.column_int(2);
  }
  const auto cells = static_cast<std::size_t>(grid.tile_size_cells * grid.tile_size_cells);
  Statement s(*writer_, "SELECT tx, ty, log_odds, m_occupied, m_empty, conflict FROM grid_tiles ORDER BY tx, ty");
  while (s.step()) {
    fusion::OccupancyGrid::TileData data;
    data.log_odds = read_floats(s, 2, cells);
    data.m_occupied = read_floats(s, 3, cells);
    data.m_empty = read_floats(s, 4, cells);
    data.conflict = read_floats(s, 5, cells);
    grid.tiles.emplace_back(fusion::TileIndex{s.column_int(0), s.column_int(1)}, std::move(data));
  }
  return grid;
}

namespace {

std::vector<std::uint32_t> read_counts(const Statement& s, int column) {
  const auto bytes = static_cast<std::size_t>(s.column_bytes(column));
  if (bytes % sizeof(std::uint32_t) != 0) throw StorageError("corrupt edge beam counts in database");
  const auto* data = static_cast<const std::uint32_t*>(s.column_blob(column));
  return std::vector<std::uint32_t>(data, data + bytes / sizeof(std::uint32_t));
}

}  // namespace

std::vector<Store::StoredEdgeBeams> Store::load_edge_beams() {
  std::lock_guard lock(writer_mutex_);
  Statement s(*writer_, "SELECT object, edge, x0, y0, x1, y1, through, ended FROM edge_beams ORDER BY object, edge");
  std::vector<StoredEdgeBeams> result;
  while (s.step()) {
    StoredEdgeBeams row;
    row.object_id = s.column_text(0);
    row.edge = s.column_int(1);
    row.beams.p0 = {s.column_double(2), s.column_double(3)};
    row.beams.p1 = {s.column_double(4), s.column_double(5)};
    row.beams.through = read_counts(s, 6);
    row.beams.ended = read_counts(s, 7);
    if (row.beams.through.size() != row.beams.ended.size() || row.edge < 0)
      throw StorageError("corrupt edge beam counts in database");
    result.push_back(std::move(row));
  }
  return result;
}

void Store::flush_grid(const StoredGrid& changed) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  run(*writer_,
      "INSERT INTO grid_meta(id, resolution, tile_size, through_scan_seq) VALUES (1, ?1, ?2, ?3) "
      "ON CONFLICT(id) DO UPDATE SET resolution = excluded.resolution, tile_size = excluded.tile_size, "
      "through_scan_seq = excluded.through_scan_seq",
      changed.resolution_m, changed.tile_size_cells, changed.through_scan_seq);
  Statement s(*writer_,
              "INSERT INTO grid_tiles(tx, ty, log_odds, m_occupied, m_empty, conflict) VALUES (?1, ?2, ?3, ?4, ?5, ?6) "
              "ON CONFLICT(tx, ty) DO UPDATE SET log_odds = excluded.log_odds, m_occupied = excluded.m_occupied, "
              "m_empty = excluded.m_empty, conflict = excluded.conflict");
  for (const auto& [index, data] : changed.tiles) {
    s.bind(1, index.x).bind(2, index.y);
    bind_floats(s, 3, data.log_odds);
    bind_floats(s, 4, data.m_occupied);
    bind_floats(s, 5, data.m_empty);
    bind_floats(s, 6, data.conflict);
    s.run();
  }
  Statement beams(*writer_,
                  "INSERT INTO edge_beams(object, edge, x0, y0, x1, y1, through, ended) "
                  "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8) ON CONFLICT(object, edge) DO UPDATE SET x0 = excluded.x0, "
                  "y0 = excluded.y0, x1 = excluded.x1, y1 = excluded.y1, through = excluded.through, "
                  "ended = excluded.ended");
  for (const auto& row : changed.edge_beams) {
    beams.bind(1, std::string_view(row.object_id)).bind(2, row.edge);
    beams.bind(3, row.beams.p0.x()).bind(4, row.beams.p0.y()).bind(5, row.beams.p1.x()).bind(6, row.beams.p1.y());
    beams.bind_blob(7, row.beams.through.data(), sizeof(std::uint32_t) * row.beams.through.size());
    beams.bind_blob(8, row.beams.ended.data(), sizeof(std::uint32_t) * row.beams.ended.size());
    beams.run();
  }
  tx.commit();
}

}  // namespace wm::storage
