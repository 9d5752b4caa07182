#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "fusion/geometry/line.h"
#include "server/world/cow_map.h"

namespace wm::world {

/// An axis-aligned box in the world frame [m].
struct Box {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;

  /// The box of a segment's endpoints, grown by `margin` on every side.
  static Box of(const fusion::LineSegment& segment, double margin = 0.0);
  bool overlaps(const Box& other) const { return x0 <= other.x1 && other.x0 <= x1 && y0 <= other.y1 && other.y0 <= y1; }
  /// Whether the segment has a point in the box (its boundary included).
  bool crossed_by(const fusion::LineSegment& segment) const;
};

/// Which keys (element numbers, CAD edges) have a box touching which square cell of the plane: the spatial index
/// of the world model. A query returns the keys registered in the cells a box touches, so matching, joining and a
/// map excerpt cost what the neighbourhood holds, not what the map holds. Cells are hashed into a fixed number of
/// buckets kept in a CowMap: copying the index (once per request, with the state) copies 256 chunk pointers, and a
/// change copies only the buckets of the cells it enters or leaves. Boost.Geometry's R-tree answers the same
/// queries but shares nothing between copies: every request would copy the whole tree.
class SpatialHash {
 public:
  static constexpr double kCellM = 4.0;
  static constexpr std::size_t kBuckets = 16384;
  /// A box over more cells than this (a 200 m diagonal), or a segment through more (10 km), is kept in one list
  /// that every query reads.
  static constexpr std::size_t kMaxCellsPerKey = 2500;

  void insert(std::int64_t key, const Box& box);
  void erase(std::int64_t key, const Box& box);
  /// The key's box changed: touches only the cells it left or entered.
  void move(std::int64_t key, const Box& from, const Box& to);

  /// A segment is registered in the cells it passes through, not in those of its bounding box: a long diagonal
  /// wall takes a few hundred cells instead of the square of that, and is not among the keys every query reads.
  /// A query finds it from any box that touches one of those cells (so from any box it has a point in).
  void insert(std::int64_t key, const fusion::LineSegment& segment);
  void erase(std::int64_t key, const fusion::LineSegment& segment);
  void move(std::int64_t key, const fusion::LineSegment& from, const fusion::LineSegment& to);
  /// Inserts many segments at once: each bucket is built and stored once (insert() copies a bucket per entry,
  /// which makes a whole plan's edges cost the square of a crowded bucket's size).
  void insert_all(const std::vector<std::pair<std::int64_t, fusion::LineSegment>>& segments);

  /// Every key registered with a box or segment that shares a cell with `box` (so every box that overlaps it, every
  /// segment with a point in it, and some near ones). Sorted, without repeats.
  std::vector<std::int64_t> query(const Box& box) const;
  /// Every key registered in a cell within `margin` of the segment's cells: what lies near a long diagonal wall,
  /// without the half of the building its bounding box holds. Sorted, without repeats.
  std::vector<std::int64_t> query(const fusion::LineSegment& segment, double margin) const;
  void clear() { buckets_.clear(); }

 private:
  struct Cell {
    std::int64_t ix = 0, iy = 0;
    auto operator<=>(const Cell&) const = default;
  };
  struct Entry {
    Cell cell;
    std::int64_t key = 0;
    auto operator<=>(const Entry&) const = default;
  };
  // Bucket kLargeBucket holds the keys whose box covers too many cells (with cell {0, 0}).
  static constexpr std::int64_t kLargeBucket = static_cast<std::int64_t>(kBuckets);

  static std::vector<Cell> cells_of(const Box& box);  // sorted; empty when the box is too large
  // The cells of the segment's pieces' boxes grown by `margin`; sorted; empty when it is too long.
  static std::vector<Cell> cells_of(const fusion::LineSegment& segment, double margin = 0.0);
  static std::int64_t bucket_of(const Cell& cell);
  void remove(std::int64_t bucket, const Entry& entry);
  void add(std::int64_t bucket, const Entry& entry);
  void insert_cells(std::int64_t key, const std::vector<Cell>& cells);
  void erase_cells(std::int64_t key, const std::vector<Cell>& cells);
  void move_cells(std::int64_t key, const std::vector<Cell>& from, const std::vector<Cell>& to);
  std::vector<std::int64_t> large_keys() const;
  /// `keys` and the keys registered in `cells`, sorted, without repeats.
  std::vector<std::int64_t> keys_in(const std::vector<Cell>& cells, std::vector<std::int64_t> keys) const;

  CowMap<std::vector<Entry>> buckets_;  // sorted entries per bucket
};

}  // namespace wm::world
