#include "server/world/spatial_hash.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <unordered_map>

namespace wm::world {
namespace {

// Cell coordinates are clamped so that a far (but finite) coordinate cannot overflow the integer cast.
constexpr double kMaxCell = 1e12;

std::int64_t cell_coordinate(double v) {
  return static_cast<std::int64_t>(std::clamp(std::floor(v / SpatialHash::kCellM), -kMaxCell, kMaxCell));
}

}  // namespace

Box Box::of(const fusion::LineSegment& segment, double margin) {
  const Eigen::Vector2d a = segment.p0(), b = segment.p1();
  return {std::min(a.x(), b.x()) - margin, std::min(a.y(), b.y()) - margin, std::max(a.x(), b.x()) + margin,
          std::max(a.y(), b.y()) + margin};
}

bool Box::crossed_by(const fusion::LineSegment& segment) const {
  if (!overlaps(of(segment))) return false;
  // Separating axes left: the segment's normal. The box's corners must not all lie strictly on one side.
  const Eigen::Vector2d a = segment.p0(), b = segment.p1(), d = b - a;
  int below = 0, above = 0;
  for (const auto& [x, y] : {std::pair{x0, y0}, std::pair{x0, y1}, std::pair{x1, y0}, std::pair{x1, y1}}) {
    const double side = d.x() * (y - a.y()) - d.y() * (x - a.x());
    below += side < 0;
    above += side > 0;
  }
  return below < 4 && above < 4;
}

std::vector<SpatialHash::Cell> SpatialHash::cells_of(const Box& box) {
  const std::int64_t ix0 = cell_coordinate(box.x0), ix1 = cell_coordinate(box.x1), iy0 = cell_coordinate(box.y0),
                     iy1 = cell_coordinate(box.y1);
  if (static_cast<double>(ix1 - ix0 + 1) * static_cast<double>(iy1 - iy0 + 1) > static_cast<double>(kMaxCellsPerKey))
    return {};
  std::vector<Cell> cells;
  for (auto ix = ix0; ix <= ix1; ++ix)
    for (auto iy = iy0; iy <= iy1; ++iy) cells.push_back({ix, iy});
  return cells;
}

std::int64_t SpatialHash::bucket_of(const Cell& cell) {
  // Neighbouring cells land in different buckets (the multipliers are large odd numbers).
  const auto h = static_cast<std::uint64_t>(cell.ix) * 0x9E3779B97F4A7C15ULL ^
                 static_cast<std::uint64_t>(cell.iy) * 0xC2B2AE3D27D4EB4FULL;
  return static_cast<std::int64_t>((h ^ (h >> 29)) % kBuckets);
}

void SpatialHash::remove(std::int64_t bucket, const Entry& entry) {
  const auto* entries = buckets_.find(bucket);
  if (!entries || !std::binary_search(entries->begin(), entries->end(), entry)) return;
  auto changed = *entries;
  changed.erase(std::lower_bound(changed.begin(), changed.end(), entry));
  if (changed.empty())
    buckets_.erase(bucket);
  else
    buckets_.put(bucket, std::move(changed));
}

void SpatialHash::add(std::int64_t bucket, const Entry& entry) {
  const auto* entries = buckets_.find(bucket);
  std::vector<Entry> changed = entries ? *entries : std::vector<Entry>{};
  const auto at = std::lower_bound(changed.begin(), changed.end(), entry);
  if (at != changed.end() && *at == entry) return;
  changed.insert(at, entry);
  buckets_.put(bucket, std::move(changed));
}

std::vector<SpatialHash::Cell> SpatialHash::cells_of(const fusion::LineSegment& segment, double margin) {
  const Eigen::Vector2d a = segment.p0(), b = segment.p1();
  const double pieces = std::ceil((b - a).norm() / kCellM);
  if (!(pieces <= static_cast<double>(kMaxCellsPerKey) / 3)) return {};  // NaN included
  // Pieces no longer than a cell: each one's box meets at most 2 × 2 cells (more by the margin), and together they
  // hold every point.
  const auto n = std::max<std::size_t>(1, static_cast<std::size_t>(pieces));
  std::vector<Cell> cells;
  Eigen::Vector2d from = a;
  for (std::size_t i = 1; i <= n; ++i) {
    const Eigen::Vector2d to =
        i == n ? b : Eigen::Vector2d(a + static_cast<double>(i) / static_cast<double>(n) * (b - a));
    const Box piece{std::min(from.x(), to.x()) - margin, std::min(from.y(), to.y()) - margin,
                    std::max(from.x(), to.x()) + margin, std::max(from.y(), to.y()) + margin};
    for (auto ix = cell_coordinate(piece.x0); ix <= cell_coordinate(piece.x1); ++ix)
      for (auto iy = cell_coordinate(piece.y0); iy <= cell_coordinate(piece.y1); ++iy) cells.push_back({ix, iy});
    from = to;
  }
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  return cells;
}

void SpatialHash::insert_cells(std::int64_t key, const std::vector<Cell>& cells) {
  if (cells.empty()) add(kLargeBucket, {{}, key});
  for (const auto& cell : cells) add(bucket_of(cell), {cell, key});
}

void SpatialHash::erase_cells(std::int64_t key, const std::vector<Cell>& cells) {
  if (cells.empty()) remove(kLargeBucket, {{}, key});
  for (const auto& cell : cells) remove(bucket_of(cell), {cell, key});
}

void SpatialHash::move_cells(std::int64_t key, const std::vector<Cell>& from, const std::vector<Cell>& to) {
  if (from.empty() || to.empty()) {
    erase_cells(key, from);
    insert_cells(key, to);
    return;
  }
  std::vector<Cell> left, entered;
  std::set_difference(from.begin(), from.end(), to.begin(), to.end(), std::back_inserter(left));
  std::set_difference(to.begin(), to.end(), from.begin(), from.end(), std::back_inserter(entered));
  for (const auto& cell : left) remove(bucket_of(cell), {cell, key});
  for (const auto& cell : entered) add(bucket_of(cell), {cell, key});
}

void SpatialHash::insert(std::int64_t key, const Box& box) { insert_cells(key, cells_of(box)); }
void SpatialHash::erase(std::int64_t key, const Box& box) { erase_cells(key, cells_of(box)); }
void SpatialHash::move(std::int64_t key, const Box& from, const Box& to) {
  move_cells(key, cells_of(from), cells_of(to));
}

void SpatialHash::insert(std::int64_t key, const fusion::LineSegment& segment) { insert_cells(key, cells_of(segment)); }
void SpatialHash::erase(std::int64_t key, const fusion::LineSegment& segment) { erase_cells(key, cells_of(segment)); }
void SpatialHash::move(std::int64_t key, const fusion::LineSegment& from, const fusion::LineSegment& to) {
  move_cells(key, cells_of(from), cells_of(to));
}

void SpatialHash::insert_all(const std::vector<std::pair<std::int64_t, fusion::LineSegment>>& segments) {
  std::unordered_map<std::int64_t, std::vector<Entry>> added;
  for (const auto& [key, segment] : segments) {
    const auto cells = cells_of(segment);
    if (cells.empty()) added[kLargeBucket].push_back({{}, key});
    for (const auto& cell : cells) added[bucket_of(cell)].push_back({cell, key});
  }
  for (auto& [bucket, entries] : added) {
    if (const auto* present = buckets_.find(bucket)) entries.insert(entries.end(), present->begin(), present->end());
    std::sort(entries.begin(), entries.end());
    entries.erase(std::unique(entries.begin(), entries.end()), entries.end());
    buckets_.put(bucket, std::move(entries));
  }
}

std::vector<std::int64_t> SpatialHash::query(const Box& box) const {
  std::vector<std::int64_t> result = large_keys();
  const auto cells = cells_of(box);
  if (cells.empty() && box.x0 <= box.x1 && box.y0 <= box.y1) {
    // A query larger than the cell limit: every entry whose cell lies in the box's range.
    const Cell lo{cell_coordinate(box.x0), cell_coordinate(box.y0)},
        hi{cell_coordinate(box.x1), cell_coordinate(box.y1)};
    for (const auto& [bucket, entries] : buckets_)
      for (const auto& entry : entries)
        if (bucket != kLargeBucket && entry.cell.ix >= lo.ix && entry.cell.ix <= hi.ix && entry.cell.iy >= lo.iy &&
            entry.cell.iy <= hi.iy)
          result.push_back(entry.key);
  }
  return keys_in(cells, std::move(result));
}

std::vector<std::int64_t> SpatialHash::query(const fusion::LineSegment& segment, double margin) const {
  const auto cells = cells_of(segment, margin);
  if (cells.empty()) return query(Box::of(segment, margin));  // too long to walk: its box answers, more widely
  return keys_in(cells, large_keys());
}

std::vector<std::int64_t> SpatialHash::large_keys() const {
  std::vector<std::int64_t> keys;
  if (const auto* large = buckets_.find(kLargeBucket))
    for (const auto& entry : *large) keys.push_back(entry.key);
  return keys;
}

std::vector<std::int64_t> SpatialHash::keys_in(const std::vector<Cell>& cells, std::vector<std::int64_t> keys) const {
  for (const auto& cell : cells) {
    const auto* entries = buckets_.find(bucket_of(cell));
    if (!entries) continue;
    // Entries are sorted by cell: the ones of this cell are one run.
    for (auto it = std::lower_bound(entries->begin(), entries->end(), Entry{cell, INT64_MIN});
         it != entries->end() && it->cell == cell; ++it)
      keys.push_back(it->key);
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  return keys;
}

}  // namespace wm::world
