// worldmodel_shm.h: the layout of wmd's shared-memory export, and a reader for it. Header-only, C++17, POSIX
// (shm_open, mmap); no dependency beyond the standard library. wmd writes the segment with the same structs.
//
// The segment (docs/shm.md has the byte table):
//   [0, 4096)             SegmentHeader
//   [tiles_offset, ...)   tile_capacity slots of slot_bytes: TileSlotHeader, then 4 layers of T² float32 each
//                         (bayes, ds_belief, ds_plausibility, ds_conflict; row-major from the tile's lower-left
//                         cell, NaN = never observed), the same values as GET /api/v1/grid/tiles/{layer}/{tx}/{ty}
//   [map_offset, ...)     MapHeader, then element_count ElementRecord, object_count ObjectRecord, edge_count
//                         EdgeRecord
//
// Consistency: every tile slot, and the map as a whole, carries a sequence counter (a seqlock). The writer makes it
// odd, writes, and makes it even again; a reader copies, then checks that the counter was even and unchanged, and
// copies again otherwise. The writer never waits for a reader, and a reader that stalls or dies holds nothing.
// Slots are only appended: a slot's (tx, ty) never changes once tile_count counts it.
//
// Typical use:
//   worldmodel::shm::Reader reader(name);   // name from GET /api/v1/shm, e.g. "wm-0b5c…"
//   auto layer = reader.read_layer(worldmodel::shm::Layer::bayes);
//   auto map = reader.read_map();
#pragma once

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace worldmodel::shm {

inline constexpr char kMagic[8] = {'W', 'M', 'S', 'H', 'M', '0', '1', '\0'};
inline constexpr std::uint32_t kLayoutVersion = 1;
inline constexpr std::uint64_t kHeaderBytes = 4096;
inline constexpr std::uint32_t kLayerCount = 4;
/// Segment names: this prefix and a UUID ("wm-0b5c2f9e-…"); the file is /dev/shm/<name> on Linux.
inline constexpr char kNamePrefix[] = "wm-";

/// The grid layers, in slot order; the names are those of GET /api/v1/grid?layer=.
enum class Layer : std::uint32_t { bayes = 0, ds_belief = 1, ds_plausibility = 2, ds_conflict = 3 };
inline const char* layer_name(Layer layer) {
  static const char* const names[kLayerCount] = {"bayes", "ds_belief", "ds_plausibility", "ds_conflict"};
  return names[static_cast<std::uint32_t>(layer)];
}

enum class SegmentState : std::uint32_t {
  live = 0,     // the server writes it
  retired = 1,  // the server moved to a larger segment: `successor` names it
  stopped = 2,  // the server stopped cleanly; the content is its last state
};

/// Bits of SegmentHeader::truncated: what did not fit under the server's size cap (--shm-max-mb, /dev/shm's room).
inline constexpr std::uint32_t kTilesTruncated = 1;
inline constexpr std::uint32_t kMapTruncated = 2;

static_assert(std::atomic<std::uint64_t>::is_always_lock_free && std::atomic<std::uint32_t>::is_always_lock_free &&
                  std::atomic<std::int64_t>::is_always_lock_free,
              "the segment's counters must be lock-free atomics to be shared between processes");

struct SegmentHeader {
  char magic[8];                         // kMagic
  std::uint32_t layout_version;          // kLayoutVersion
  std::uint32_t header_bytes;            // kHeaderBytes
  std::atomic<std::uint32_t> state;      // SegmentState
  std::atomic<std::uint32_t> truncated;  // kTilesTruncated | kMapTruncated
  std::int64_t owner_pid;                // the wmd process
  std::uint64_t owner_start_ticks;       // its start time (/proc/<pid>/stat field 22): tells a reused pid
  char server_instance[48];              // the run's token, as in GET /api/v1/map's server_instance
  char successor[64];                    // when retired: the next segment's name (NUL-terminated)
  std::int64_t tile_size_cells;          // T
  double resolution_m;                   // cell side
  std::uint32_t layer_count;             // kLayerCount
  std::uint32_t reserved0;
  std::uint64_t slot_bytes;                   // one tile slot: TileSlotHeader + 4·T² floats, rounded up to 64
  std::uint64_t tiles_offset;                 // first slot, from the segment's start
  std::uint64_t tile_capacity;                // slots
  std::atomic<std::uint64_t> tile_count;      // slots in use; a slot is whole before it is counted
  std::atomic<std::uint64_t> grid_revision;   // scans in the grid: the slots hold every scan up to this one
  std::uint64_t map_offset;                   // the MapHeader
  std::uint64_t map_capacity_bytes;           // MapHeader and records
  std::atomic<std::int64_t> updated_unix_ns;  // the end of the server's last pass
  std::uint64_t segment_bytes;                // the whole segment
};

struct TileSlotHeader {
  std::atomic<std::uint64_t> sequence;  // odd while the writer changes the slot
  std::int64_t tx;                      // tile (tx, ty) holds cells [tx·T, (tx+1)·T) × [ty·T, (ty+1)·T)
  std::int64_t ty;
  std::uint64_t revision;  // the tile's revision (as GET /api/v1/grid/tiles lists it), under the sequence
  std::uint64_t reserved[4];
};

struct MapHeader {
  std::atomic<std::uint64_t> sequence;  // odd while the writer changes the map
  std::int64_t version;                 // the map version (GET /api/v1/map's "version")
  std::uint64_t element_count;
  std::uint64_t object_count;
  std::uint64_t edge_count;
  std::uint64_t reserved[3];
};

/// An observed element ("e<number>"), a segment the floor plan does not explain.
struct ElementRecord {
  std::int64_t number;
  double x1, y1, x2, y2;  // world frame [m]
  std::int64_t support;   // observations fused into it
  std::int64_t updated_version;
  std::uint32_t origin;  // 0 client, 1 scan, 2 grid, 3 other
  std::uint32_t reserved;
};

/// A CAD object of the floor plan, as placed and posed now.
struct ObjectRecord {
  double x, y, theta;        // pose in the world [m, m, rad]
  std::uint32_t first_edge;  // its edges are edges[first_edge, first_edge + edge_count)
  std::uint32_t edge_count;
  std::uint32_t flags;      // 1 solid, 2 not_deformable, 4 id longer than 128 bytes, truncated
  std::uint32_t id_length;  // bytes of id used
  char id[128];             // not NUL-terminated when 128 long
  char kind[24];            // NUL-padded, truncated
};
inline constexpr std::uint32_t kObjectSolid = 1;
inline constexpr std::uint32_t kObjectNotDeformable = 2;
inline constexpr std::uint32_t kObjectIdTruncated = 4;

/// One edge of a CAD object in the world frame.
struct EdgeRecord {
  double x1, y1, x2, y2;
  std::uint32_t object_index;  // into the objects
  std::uint32_t edge_index;    // within its object
  std::uint64_t reserved;
};

static_assert(sizeof(TileSlotHeader) == 64 && sizeof(MapHeader) == 64 && sizeof(ElementRecord) == 64 &&
                  sizeof(ObjectRecord) == 192 && sizeof(EdgeRecord) == 48 && sizeof(SegmentHeader) <= kHeaderBytes,
              "the segment layout is fixed: docs/shm.md");
static_assert(offsetof(SegmentHeader, state) == 16 && offsetof(SegmentHeader, owner_pid) == 24 &&
                  offsetof(SegmentHeader, server_instance) == 40 && offsetof(SegmentHeader, successor) == 88 &&
                  offsetof(SegmentHeader, tile_size_cells) == 152 && offsetof(SegmentHeader, slot_bytes) == 176 &&
                  offsetof(SegmentHeader, tile_count) == 200 && offsetof(SegmentHeader, grid_revision) == 208 &&
                  offsetof(SegmentHeader, map_offset) == 216 && offsetof(SegmentHeader, updated_unix_ns) == 232 &&
                  offsetof(SegmentHeader, segment_bytes) == 240,
              "the segment layout is fixed: docs/shm.md");

/// Bytes of one tile slot for tiles of `tile_size_cells`.
inline std::uint64_t slot_bytes_for(std::int64_t tile_size_cells) {
  const auto bytes = sizeof(TileSlotHeader) + kLayerCount * static_cast<std::uint64_t>(tile_size_cells) *
                                                  static_cast<std::uint64_t>(tile_size_cells) * sizeof(float);
  return (bytes + 63) / 64 * 64;
}

/// Thrown for a segment that cannot be opened or does not hold the expected layout, and for a slot or map that
/// stays in an update far longer than any write takes (a writer that died mid-write).
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A read-only mapping of one segment. Every read copies out under the seqlock, so the values returned are one
/// whole state of the tile (or the map), never a mix of two.
class Reader {
 public:
  struct TileKey {
    std::int64_t tx = 0;
    std::int64_t ty = 0;
  };
  /// A layer over the smallest block of tiles holding every exported one (the region GET /api/v1/grid answers
  /// without a bbox): cell (col, row) is values[row·width + col], row 0 at the bottom; its lower-left corner is at
  /// ((x0_cells + col)·resolution, (y0_cells + row)·resolution).
  struct Dense {
    std::int64_t x0_cells = 0;
    std::int64_t y0_cells = 0;
    std::int64_t width = 0;
    std::int64_t height = 0;
    double resolution_m = 0;
    std::uint64_t grid_revision = 0;  // the tiles read hold every scan up to this one
    std::vector<float> values;
  };
  struct Map {
    std::int64_t version = 0;
    std::vector<ElementRecord> elements;
    std::vector<ObjectRecord> objects;
    std::vector<EdgeRecord> edges;
  };

  /// Opens "wm-<uuid>" (or "/dev/shm/wm-<uuid>"). @throw Error when it does not exist, is not a regular file,
  /// cannot be mapped, or is not a worldmodel segment of this layout version.
  explicit Reader(std::string name) : name_(strip(std::move(name))) {
    // Anyone may put a file of that name in /dev/shm: O_NONBLOCK so that a FIFO does not block the open (glibc's
    // shm_open passes it on, and adds O_NOFOLLOW), then only a regular file is taken.
    const int fd = ::shm_open(("/" + name_).c_str(), O_RDONLY | O_NONBLOCK, 0);
    if (fd < 0) throw Error("cannot open shared memory '" + name_ + "': " + std::strerror(errno));
    struct stat info {};
    if (::fstat(fd, &info) != 0 || !S_ISREG(info.st_mode)) {
      ::close(fd);
      throw Error("shared memory '" + name_ + "' is not a regular file");
    }
    if (info.st_size < static_cast<off_t>(kHeaderBytes)) {
      ::close(fd);
      throw Error("shared memory '" + name_ + "' is too small to be a worldmodel segment");
    }
    size_ = static_cast<std::size_t>(info.st_size);
    void* base = ::mmap(nullptr, size_, PROT_READ, MAP_SHARED, fd, 0);
    ::close(fd);  // the mapping stays valid (and so does the memory, even after the server unlinks the name)
    if (base == MAP_FAILED) throw Error("cannot map '" + name_ + "': " + std::strerror(errno));
    base_ = static_cast<const unsigned char*>(base);
    if (!layout_fits(header(), size_)) {
      release();
      throw Error("'" + name_ + "' is not a worldmodel segment of layout version " + std::to_string(kLayoutVersion));
    }
    // Kept as checked: the file's owner could change the header afterwards, and no read goes by it again.
    const auto& h = header();
    geometry_ = {h.tile_size_cells, h.resolution_m, h.tiles_offset,      h.slot_bytes,
                 h.tile_capacity,   h.map_offset,   h.map_capacity_bytes};
  }
  ~Reader() { release(); }
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;
  Reader(Reader&& other) noexcept
      : name_(std::move(other.name_)), base_(other.base_), size_(other.size_), geometry_(other.geometry_) {
    other.base_ = nullptr;
  }
  Reader& operator=(Reader&& other) noexcept {
    if (this != &other) {
      release();
      name_ = std::move(other.name_);
      base_ = other.base_;
      size_ = other.size_;
      geometry_ = other.geometry_;
      other.base_ = nullptr;
    }
    return *this;
  }

  const std::string& name() const { return name_; }
  const SegmentHeader& header() const { return *reinterpret_cast<const SegmentHeader*>(base_); }
  SegmentState state() const { return static_cast<SegmentState>(header().state.load(std::memory_order_acquire)); }
  /// The segment that replaced this one (state() == retired), else nullopt. Open it to keep reading.
  std::optional<std::string> successor() const {
    if (state() != SegmentState::retired) return std::nullopt;
    const auto& s = header().successor;
    return std::string(s, ::strnlen(s, sizeof s));
  }
  std::int64_t tile_size_cells() const { return geometry_.tile_size_cells; }
  double resolution_m() const { return geometry_.resolution_m; }
  std::uint64_t grid_revision() const { return header().grid_revision.load(std::memory_order_acquire); }
  std::size_t tile_count() const {
    const auto count = header().tile_count.load(std::memory_order_acquire);
    return static_cast<std::size_t>(count < geometry_.tile_capacity ? count : geometry_.tile_capacity);
  }
  /// The tile in slot `slot` (< tile_count()).
  TileKey tile_key(std::size_t slot) const {
    const auto& s = slot_header(slot);
    return {s.tx, s.ty};
  }

  /// Copies one layer of slot `slot` into out[0 .. T²) and returns the tile's revision.
  std::uint64_t read_tile(std::size_t slot, Layer layer, float* out) const {
    const auto cells = cells_per_tile();
    return read_slot(slot, static_cast<std::size_t>(layer) * cells, cells, out);
  }
  /// Copies all four layers of slot `slot` (layer by layer, T² each) into out[0 .. 4·T²); one revision for all.
  std::uint64_t read_tile_layers(std::size_t slot, float* out) const {
    return read_slot(slot, 0, kLayerCount * cells_per_tile(), out);
  }

  Dense read_layer(Layer layer) const {
    Dense dense;
    read_layer(layer, dense);
    return dense;
  }
  /// The same into `dense`, reusing its memory: a reader polling the grid allocates (and faults in) nothing after
  /// the first call. Each tile's rows go straight into place under its seqlock; only the blocks no tile holds are
  /// filled with NaN.
  /// Largest region read_layer() makes [cells] (1 GiB of floats).
  static constexpr std::uint64_t kMaxDenseCells = std::uint64_t{1} << 28;

  void read_layer(Layer layer, Dense& dense) const {
    dense.resolution_m = resolution_m();
    dense.grid_revision = grid_revision();  // before the tiles: they hold at least the scans up to this one
    const auto count = tile_count();        // later slots are left for the next call
    dense.x0_cells = dense.y0_cells = dense.width = dense.height = 0;
    dense.values.clear();
    if (count == 0) return;
    const std::int64_t t = tile_size_cells();
    // The keys are read once: everything below uses these, whatever the mapping holds meanwhile.
    std::vector<TileKey> keys(count);
    auto min_x = std::numeric_limits<std::int64_t>::max(), min_y = min_x;
    auto max_x = std::numeric_limits<std::int64_t>::min(), max_y = max_x;
    for (std::size_t i = 0; i < count; ++i) {
      const auto key = keys[i] = tile_key(i);
      min_x = key.tx < min_x ? key.tx : min_x;
      min_y = key.ty < min_y ? key.ty : min_y;
      max_x = key.tx > max_x ? key.tx : max_x;
      max_y = key.ty > max_y ? key.ty : max_y;
    }
    // Spans in unsigned arithmetic (no overflow for any keys), then a bound on the cells before any allocation.
    const auto span_x = static_cast<std::uint64_t>(max_x) - static_cast<std::uint64_t>(min_x) + 1;
    const auto span_y = static_cast<std::uint64_t>(max_y) - static_cast<std::uint64_t>(min_y) + 1;
    const auto cells = static_cast<std::uint64_t>(t) * static_cast<std::uint64_t>(t);
    if (span_x == 0 || span_y == 0 || span_x > kMaxDenseCells / cells || span_y > kMaxDenseCells / cells ||
        span_x * span_y > kMaxDenseCells / cells)
      throw Error("the tiles span more than " + std::to_string(kMaxDenseCells) + " cells: read them one by one");
    const auto blocks_x = static_cast<std::int64_t>(span_x), blocks_y = static_cast<std::int64_t>(span_y);
    dense.x0_cells = min_x * t;
    dense.y0_cells = min_y * t;
    dense.width = blocks_x * t;
    dense.height = blocks_y * t;
    dense.values.resize(static_cast<std::size_t>(dense.width * dense.height));
    std::vector<bool> held(static_cast<std::size_t>(blocks_x * blocks_y), false);
    const auto at = [&](std::int64_t bx, std::int64_t by) {
      return dense.values.data() + static_cast<std::size_t>(by * t * dense.width + bx * t);
    };
    for (std::size_t i = 0; i < count; ++i) {
      const auto& key = keys[i];
      held[static_cast<std::size_t>((key.ty - min_y) * blocks_x + (key.tx - min_x))] = true;
      read_slot_rows(i, static_cast<std::size_t>(layer) * cells_per_tile(), at(key.tx - min_x, key.ty - min_y),
                     static_cast<std::size_t>(dense.width));
    }
    for (std::int64_t by = 0; by < blocks_y; ++by)
      for (std::int64_t bx = 0; bx < blocks_x; ++bx)
        if (!held[static_cast<std::size_t>(by * blocks_x + bx)])
          for (std::int64_t row = 0; row < t; ++row)
            std::fill_n(at(bx, by) + row * dense.width, t, std::numeric_limits<float>::quiet_NaN());
  }

  /// The map's version, without copying the map (to poll for a change before read_map()).
  std::int64_t map_version() const {
    const auto* map = reinterpret_cast<const MapHeader*>(base_ + geometry_.map_offset);
    for (Backoff backoff("the map", 0);; backoff.wait()) {
      const auto before = map->sequence.load(std::memory_order_acquire);
      if (before % 2 != 0) continue;
      const auto version = map->version;
      std::atomic_thread_fence(std::memory_order_acquire);
      if (map->sequence.load(std::memory_order_relaxed) == before) return version;
    }
  }

  /// A copy of the vector map, one version of it.
  Map read_map() const {
    const auto* map = reinterpret_cast<const MapHeader*>(base_ + geometry_.map_offset);
    const auto* records = base_ + geometry_.map_offset + sizeof(MapHeader);
    Map result;
    for (Backoff backoff("the map", 0);; backoff.wait()) {
      const auto before = map->sequence.load(std::memory_order_acquire);
      if (before % 2 == 0) {
        result.version = map->version;
        const std::uint64_t elements = map->element_count, objects = map->object_count, edges = map->edge_count;
        const auto bytes =
            elements * sizeof(ElementRecord) + objects * sizeof(ObjectRecord) + edges * sizeof(EdgeRecord);
        // Counts read mid-update may be garbage: copy only what the region can hold, and check afterwards.
        const auto room = geometry_.map_capacity_bytes - sizeof(MapHeader);
        if (elements <= room / sizeof(ElementRecord) && objects <= room / sizeof(ObjectRecord) &&
            edges <= room / sizeof(EdgeRecord) && bytes <= room) {
          result.elements.resize(elements);
          result.objects.resize(objects);
          result.edges.resize(edges);
          // memcpy must not get the null data() of an empty vector, even for 0 bytes.
          const auto copy = [](auto& to, const unsigned char* from) {
            if (!to.empty()) std::memcpy(to.data(), from, to.size() * sizeof to[0]);
          };
          copy(result.elements, records);
          copy(result.objects, records + elements * sizeof(ElementRecord));
          copy(result.edges, records + elements * sizeof(ElementRecord) + objects * sizeof(ObjectRecord));
          std::atomic_thread_fence(std::memory_order_acquire);
          if (map->sequence.load(std::memory_order_relaxed) == before) return result;
        }
      }
    }
  }

 private:
  // Any local user may put a "wm-…" file in /dev/shm: every size and offset is checked against the mapping, without
  // overflow, before anything is read through it.
  static bool layout_fits(const SegmentHeader& h, std::size_t size) {
    if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0 || h.layout_version != kLayoutVersion ||
        h.layer_count != kLayerCount || h.tile_size_cells < 1 || h.tile_size_cells > 1024 || h.segment_bytes > size)
      return false;
    if (h.tiles_offset % 64 != 0 || h.map_offset % 64 != 0 || h.slot_bytes % 64 != 0 ||
        h.slot_bytes < slot_bytes_for(h.tile_size_cells) || h.tiles_offset < kHeaderBytes || h.tiles_offset > size ||
        h.tile_capacity > (size - h.tiles_offset) / h.slot_bytes)
      return false;
    return h.map_offset <= size && h.map_capacity_bytes >= sizeof(MapHeader) &&
           h.map_capacity_bytes <= size - h.map_offset;
  }
  static std::string strip(std::string name) {
    const std::string dir = "/dev/shm/";
    if (name.rfind(dir, 0) == 0) name.erase(0, dir.size());
    if (!name.empty() && name.front() == '/') name.erase(0, 1);
    return name;
  }
  void release() {
    if (base_ != nullptr) ::munmap(const_cast<unsigned char*>(base_), size_);
    base_ = nullptr;
  }
  std::size_t cells_per_tile() const {
    return static_cast<std::size_t>(tile_size_cells()) * static_cast<std::size_t>(tile_size_cells());
  }
  const TileSlotHeader& slot_header(std::size_t slot) const {
    if (slot >= tile_count()) throw std::out_of_range("no tile slot " + std::to_string(slot));
    return *reinterpret_cast<const TileSlotHeader*>(base_ + geometry_.tiles_offset + slot * geometry_.slot_bytes);
  }
  // Seqlock read (Boehm, "Can seqlocks get along with programming language memory models?", 2012): the copy is
  // bracketed by an acquire load of the counter and an acquire fence before its second load.
  std::uint64_t read_slot(std::size_t slot, std::size_t first_value, std::size_t values, float* out) const {
    const auto& s = slot_header(slot);
    const auto* data =
        reinterpret_cast<const float*>(reinterpret_cast<const unsigned char*>(&s) + sizeof(TileSlotHeader));
    for (Backoff backoff("tile slot ", slot);; backoff.wait()) {
      const auto before = s.sequence.load(std::memory_order_acquire);
      if (before % 2 == 0) {
        const auto revision = s.revision;
        std::memcpy(out, data + first_value, values * sizeof(float));
        std::atomic_thread_fence(std::memory_order_acquire);
        if (s.sequence.load(std::memory_order_relaxed) == before) return revision;
      }
    }
  }
  // read_slot for one layer, row by row into a destination `stride` floats wide.
  std::uint64_t read_slot_rows(std::size_t slot, std::size_t first_value, float* out, std::size_t stride) const {
    const auto& s = slot_header(slot);
    const auto* data =
        reinterpret_cast<const float*>(reinterpret_cast<const unsigned char*>(&s) + sizeof(TileSlotHeader)) +
        first_value;
    const auto t = static_cast<std::size_t>(tile_size_cells());
    for (Backoff backoff("tile slot ", slot);; backoff.wait()) {
      const auto before = s.sequence.load(std::memory_order_acquire);
      if (before % 2 == 0) {
        const auto revision = s.revision;
        for (std::size_t row = 0; row < t; ++row) std::memcpy(out + row * stride, data + row * t, t * sizeof(float));
        std::atomic_thread_fence(std::memory_order_acquire);
        if (s.sequence.load(std::memory_order_relaxed) == before) return revision;
      }
    }
  }
  // Retries spin a little, then yield. A write takes microseconds; a counter odd for two seconds means the writer
  // died in the middle.
  class Backoff {
   public:
    Backoff(const char* what, std::size_t slot) : what_(what), slot_(slot) {}
    void wait() {
      if (++attempts_ < 64) return;
      const auto now = std::chrono::steady_clock::now();
      if (attempts_ == 64) since_ = now;
      if (now - since_ > std::chrono::seconds(2))
        throw Error(std::string(what_) + (what_.back() == ' ' ? std::to_string(slot_) : std::string()) +
                    " stayed in an update for 2 s: has the server died mid-write?");
      std::this_thread::yield();
    }

   private:
    std::string_view what_;
    std::size_t slot_;
    std::uint64_t attempts_ = 0;
    std::chrono::steady_clock::time_point since_{};
  };

  struct Geometry {
    std::int64_t tile_size_cells = 0;
    double resolution_m = 0;
    std::uint64_t tiles_offset = 0;
    std::uint64_t slot_bytes = 0;
    std::uint64_t tile_capacity = 0;
    std::uint64_t map_offset = 0;
    std::uint64_t map_capacity_bytes = 0;
  };

  std::string name_;
  const unsigned char* base_ = nullptr;
  std::size_t size_ = 0;
  Geometry geometry_;
};

}  // namespace worldmodel::shm
