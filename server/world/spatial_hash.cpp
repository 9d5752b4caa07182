#include "server/world/spatial_hash.h"

#include <algorithm>
#include <cmath>
#include <iterator>

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

void SpatialHash::insert(std::int64_t key, const Box& box) {
  const auto cells = cells_of(box);
  if (cells.empty()) add(kLargeBucket, {{}, key});
  for (const auto& cell : cells) add(bucket_of(cell), {cell, key});
}

void SpatialHash::erase(std::int64_t key, const Box& box) {
  const auto cells = cells_of(box);
  if (cells.empty()) remove(kLargeBucket, {{}, key});
  for (const auto& cell : cells) remove(bucket_of(cell), {cell, key});
}

void SpatialHash::move(std::int64_t key, const Box& from, const Box& to) {
  const auto old_cells = cells_of(from), new_cells = cells_of(to);
  if (old_cells.empty() || new_cells.empty()) {
    erase(key, from);
    insert(key, to);
    return;
  }
  std::vector<Cell> left, entered;
  std::set_difference(old_cells.begin(), old_cells.end(), new_cells.begin(), new_cells.end(), std::back_inserter(left));
  std::set_difference(new_cells.begin(), new_cells.end(), old_cells.begin(), old_cells.end(),
                      std::back_inserter(entered));
  for (const auto& cell : left) remove(bucket_of(cell), {cell, key});
  for (const auto& cell : entered) add(bucket_of(cell), {cell, key});
}

std::vector<std::int64_t> SpatialHash::query(const Box& box) const {
  std::vector<std::int64_t> result;
  if (const auto* large = buckets_.find(kLargeBucket))
    for (const auto& entry : *large) result.push_back(entry.key);
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
  for (const auto& cell : cells) {
    const auto* entries = buckets_.find(bucket_of(cell));
    if (!entries) continue;
    // Entries are sorted by cell: the ones of this cell are one run.
    for (auto it = std::lower_bound(entries->begin(), entries->end(), Entry{cell, INT64_MIN});
         it != entries->end() && it->cell == cell; ++it)
      result.push_back(it->key);
  }
  std::sort(result.begin(), result.end());
  result.erase(std::unique(result.begin(), result.end()), result.end());
  return result;
}

}  // namespace wm::world
