#include "server/shm/shared_map_export.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <boost/interprocess/mapped_region.hpp>
#include <boost/interprocess/shared_memory_object.hpp>
#include <boost/uuid/uuid_generators.hpp>
#include <boost/uuid/uuid_io.hpp>
#include <cerrno>
#include <cstring>

#include "server/shm/segment_files.h"
#include "server/shm/sigbus_guard.h"
#include "wire/shm/worldmodel_shm.h"

namespace wm::shm {
namespace {

using internal::free_shm_bytes;
using internal::kShmDir;
using internal::process_stat;
using internal::ProcessStat;

namespace bip = boost::interprocess;
namespace layout = worldmodel::shm;

constexpr std::uint64_t kPage = 4096;
constexpr std::uint64_t kMinTileBytes = std::uint64_t{4} << 20;  // a first segment's tiles: 64 tiles of 64²
constexpr std::uint64_t kMinMapBytes = std::uint64_t{256} << 10;

std::uint64_t round_up(std::uint64_t n, std::uint64_t to) { return (n + to - 1) / to * to; }

std::int64_t unix_ns_now() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void copy_text(char* to, std::size_t size, const std::string& text) {
  std::memset(to, 0, size);
  std::memcpy(to, text.data(), std::min(text.size(), size - 1));
}

std::uint32_t origin_code(const std::string& origin) {
  if (origin == "client") return 0;
  if (origin == "scan") return 1;
  if (origin == "grid") return 2;
  return 3;
}

}  // namespace

/// One segment this process made: created, its pages reserved, mapped read-write.
///
/// Any process of this user may rewrite the file or shrink it. So the layout is kept here, as computed, and never
/// read back from the mapping (every address below comes from `layout_`), and every access to the mapping goes
/// through guard(): a truncation under it costs the segment (lost()), never the process.
class SharedMapExport::Segment {
 public:
  /// Where everything is [bytes from the segment's start].
  struct Layout {
    std::int64_t tile_size_cells = 0;
    std::uint64_t bytes = 0;
    std::uint64_t tiles_offset = 0;
    std::uint64_t slot_bytes = 0;
    std::uint64_t tile_capacity = 0;
    std::uint64_t map_offset = 0;
    std::uint64_t map_capacity_bytes = 0;
  };

  Segment(std::string name, const Layout& layout) : name_(std::move(name)), layout_(layout) {
    const auto bytes = layout_.bytes;
    bip::permissions permissions;
    permissions.set_permissions(0644);  // others may read, as they may GET the map over loopback
    object_ = bip::shared_memory_object(bip::create_only, name_.c_str(), bip::read_write, permissions);
    try {
      // Held while this process runs (remove_stale_segments takes what no one holds); the fd stays open in object_.
      if (::flock(object_.get_mapping_handle().handle, LOCK_SH) != 0)
        throw std::runtime_error(std::string("cannot lock the segment: ") + std::strerror(errno));
      object_.truncate(static_cast<bip::offset_t>(bytes));
      // tmpfs hands out pages on first write; a full /dev/shm would then kill the server with SIGBUS mid-copy.
      // Reserving every page now turns that into an error here.
      if (const int error = ::posix_fallocate(object_.get_mapping_handle().handle, 0, static_cast<off_t>(bytes)))
        throw std::runtime_error("cannot reserve " + std::to_string(bytes >> 20) +
                                 " MB in /dev/shm: " + std::strerror(error));
      region_ = bip::mapped_region(object_, bip::read_write);
    } catch (...) {
      bip::shared_memory_object::remove(name_.c_str());
      throw;
    }
  }
  ~Segment() = default;

  const std::string& name() const { return name_; }
  const Layout& layout() const { return layout_; }
  /// Every access to the mapping is made while one of these lives.
  SigbusGuard guard() { return SigbusGuard(region_.get_address(), region_.get_size(), lost_); }
  unsigned char* base() { return static_cast<unsigned char*>(region_.get_address()); }
  layout::SegmentHeader& header() { return *reinterpret_cast<layout::SegmentHeader*>(base()); }
  layout::TileSlotHeader& slot(std::uint64_t index) {
    if (index >= layout_.tile_capacity) throw std::logic_error("shared memory slot " + std::to_string(index));
    return *reinterpret_cast<layout::TileSlotHeader*>(base() + layout_.tiles_offset + index * layout_.slot_bytes);
  }
  layout::MapHeader& map() { return *reinterpret_cast<layout::MapHeader*>(base() + layout_.map_offset); }
  void unlink() { bip::shared_memory_object::remove(name_.c_str()); }

  /// A guarded access faulted: the file was shrunk under the mapping, which no longer reaches it.
  bool lost() const { return lost_.load(std::memory_order_relaxed); }
  /// Whether readers still find the segment as it was made: not lost, the file not shorter than the segment, and
  /// the header's layout fields as this process wrote them. Otherwise it is to be replaced.
  bool intact() {
    struct stat info {};
    if (lost() || ::fstat(object_.get_mapping_handle().handle, &info) != 0 ||
        static_cast<std::uint64_t>(info.st_size) < layout_.bytes)
      return false;
    const auto guarded = guard();
    const auto& h = header();
    const bool same = std::memcmp(h.magic, layout::kMagic, sizeof h.magic) == 0 &&
                      h.layout_version == layout::kLayoutVersion && h.header_bytes == layout::kHeaderBytes &&
                      h.layer_count == layout::kLayerCount && h.tile_size_cells == layout_.tile_size_cells &&
                      h.slot_bytes == layout_.slot_bytes && h.tiles_offset == layout_.tiles_offset &&
                      h.tile_capacity == layout_.tile_capacity && h.map_offset == layout_.map_offset &&
                      h.map_capacity_bytes == layout_.map_capacity_bytes && h.segment_bytes == layout_.bytes;
    return same && !lost();
  }

 private:
  std::string name_;
  const Layout layout_;
  bip::shared_memory_object object_;
  bip::mapped_region region_;
  std::atomic<bool> lost_{false};
};

SharedMapExport::SharedMapExport(ExportSource world, ShmOptions options, std::string server_instance,
                                 common::Diagnostics& diagnostics, events::EventHub* events)
    : world_(world),
      diagnostics_(diagnostics),
      options_(options),
      server_instance_(std::move(server_instance)),
      events_(events) {
  const auto tiles = world_.grid.grid_tiles();
  tile_size_cells_ = tiles.tile_size_cells;
  resolution_m_ = tiles.resolution_m;
  owner_start_ticks_ = process_stat(::getpid()).value_or(ProcessStat{}).start_ticks;
  for (const auto& name : remove_stale_segments())
    diagnostics_.report(common::Severity::info, "shm",
                        "removed shared memory " + name + " left by a server that is gone");
  // Subscribed before the first pass: nothing that happens after it goes unseen.
  if (events_)
    subscriber_ = events_->subscribe(
        [this] {
          {
            std::lock_guard lock(wake_mutex_);
            changed_ = true;
          }
          wake_.notify_one();
        },
        /*wants_json=*/false);
  sync();
  try {
    thread_ = std::thread([this] { run(); });
  } catch (...) {
    if (segment_) segment_->unlink();
    throw;
  }
}

SharedMapExport::~SharedMapExport() {
  if (subscriber_) events_->unsubscribe(subscriber_);  // not under wake_mutex_: the hub's wake takes it
  {
    std::lock_guard lock(wake_mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  std::lock_guard lock(mutex_);
  if (segment_) {
    {
      const auto guard = segment_->guard();
      segment_->header().state.store(static_cast<std::uint32_t>(layout::SegmentState::stopped),
                                     std::memory_order_release);
    }
    segment_->unlink();
  }
}

void SharedMapExport::run() {
  // At most a tenth of one core: during full-rate ingest every pass finds most tiles changed, and copying them as
  // often as an idle server could would take the CPU ingest needs.
  constexpr int kPauseToWork = 9;
  std::unique_lock lock(wake_mutex_);
  auto pause = std::chrono::duration_cast<std::chrono::steady_clock::duration>(options_.period);
  while (!wake_.wait_for(lock, pause, [this] { return stopping_; })) {
    if (subscriber_) {
      wake_.wait_for(lock, options_.idle_period, [this] { return stopping_ || changed_; });
      if (stopping_) break;
      changed_ = false;
    }
    lock.unlock();
    if (subscriber_) subscriber_->take();  // any event is reason enough to look; its kind does not matter here
    const auto start = std::chrono::steady_clock::now();
    sync();
    pause = std::max<std::chrono::steady_clock::duration>(options_.period,
                                                          kPauseToWork * (std::chrono::steady_clock::now() - start));
    lock.lock();
  }
}

void SharedMapExport::sync() {
  std::lock_guard lock(mutex_);
  const auto before = error_;
  try {
    sync_locked();
    // Shrunk under this pass: replaced now rather than a period later.
    if (segment_ && segment_->lost()) sync_locked();
  } catch (const std::exception& e) {
    error_ = e.what();  // the service keeps serving HTTP; the next pass tries again
  }
  if (!error_.empty() && error_ != before)
    diagnostics_.report(common::Severity::warning, "shm", "shared memory export: " + error_);
}

void SharedMapExport::sync_locked() {
  const auto tiles = world_.grid.grid_tiles();
  const auto state = world_.map.snapshot();

  // Another process of this user shrank the file or rewrote the header: a new segment takes its place, filled from
  // the world (nothing is copied from this one), and this one is retired with the new name where it still can be.
  const bool replace = segment_ && !segment_->intact();
  if (replace) {
    diagnostics_.report(
        common::Severity::warning, "shm",
        "shared memory " + segment_->name() + " was truncated or changed by another process: it is replaced");
    slots_.clear();
    map_version_ = -1;
  }

  // The map's records, made before any segment is touched, so its size is known.
  std::vector<unsigned char> records;
  std::uint64_t element_count = 0, object_count = 0, edge_count = 0;
  // A map clipped to a full segment is written again once a larger one may hold it.
  const bool map_changed = state->version != map_version_ || !counts_.map_complete;
  if (map_changed) {
    std::vector<layout::ElementRecord> elements;
    elements.reserve(state->elements.size());
    for (const auto& [number, element] : state->elements) {
      const auto p0 = element.segment.p0(), p1 = element.segment.p1();
      elements.push_back({number, p0.x(), p0.y(), p1.x(), p1.y(), element.support, element.updated_version,
                          origin_code(element.origin), 0});
    }
    std::vector<layout::ObjectRecord> objects;
    std::vector<layout::EdgeRecord> edges;
    for (const auto& object : state->objects) {
      layout::ObjectRecord record{};
      const auto& pose = object.body.pose();
      record.x = pose.x_m;
      record.y = pose.y_m;
      record.theta = pose.theta_rad;
      record.first_edge = static_cast<std::uint32_t>(edges.size());
      const auto world_edges = object.body.world_edges(Eigen::Matrix2d::Zero());
      record.edge_count = static_cast<std::uint32_t>(world_edges.size());
      const auto& id = object.plan->id;
      record.flags = (object.plan->has_attribute("solid") ? layout::kObjectSolid : 0) |
                     (object.plan->has_attribute("not_deformable") ? layout::kObjectNotDeformable : 0) |
                     (id.size() > sizeof record.id ? layout::kObjectIdTruncated : 0);
      record.id_length = static_cast<std::uint32_t>(std::min(id.size(), sizeof record.id));
      std::memcpy(record.id, id.data(), record.id_length);
      copy_text(record.kind, sizeof record.kind, object.plan->kind);
      for (std::size_t k = 0; k < world_edges.size(); ++k) {
        const auto a = world_edges[k].p0(), b = world_edges[k].p1();
        edges.push_back(
            {a.x(), a.y(), b.x(), b.y(), static_cast<std::uint32_t>(objects.size()), static_cast<std::uint32_t>(k), 0});
      }
      objects.push_back(record);
    }
    element_count = elements.size();
    object_count = objects.size();
    edge_count = edges.size();
    const auto append = [&records](const auto& items) {
      const auto* bytes = reinterpret_cast<const unsigned char*>(items.data());
      records.insert(records.end(), bytes, bytes + items.size() * sizeof items[0]);
    };
    append(elements);
    append(objects);
    append(edges);
    map_bytes_needed_ = sizeof(layout::MapHeader) + records.size();
  }

  const auto new_tiles = [&] {
    std::uint64_t count = 0;
    for (const auto& t : tiles.tiles) count += slots_.count({t.tx, t.ty}) == 0 ? 1 : 0;
    return count;
  }();
  const auto tiles_needed = slots_.size() + new_tiles;
  if (replace || !segment_ || tiles_needed > segment_->layout().tile_capacity ||
      map_bytes_needed_ > segment_->layout().map_capacity_bytes) {
    const bool grown = grow(tiles_needed, map_bytes_needed_, /*copy=*/!replace);
    if (!grown && replace) {  // no new segment: writing on into the damaged one would help no reader
      segment_->unlink();
      segment_.reset();
    }
    if (!segment_ || (!grown && segment_->lost())) return;  // status() says why; a lost one is replaced next
  }
  const auto guard = segment_->guard();
  auto& header = segment_->header();

  bool tiles_truncated = false;
  for (const auto& t : tiles.tiles) {
    if (segment_->lost()) return;  // the rest would go nowhere: sync() replaces the segment
    auto slot = slots_.find({t.tx, t.ty});
    if (slot != slots_.end() && slot->second.revision == t.revision) continue;
    const bool fresh = slot == slots_.end();
    if (fresh && slots_.size() >= segment_->layout().tile_capacity) {
      tiles_truncated = true;
      continue;
    }
    const auto values = world_.grid.grid_tile_layers(t.tx, t.ty);  // may be newer than t.revision: never older
    if (!values) continue;
    if (fresh) slot = slots_.emplace(std::pair{t.tx, t.ty}, Slot{slots_.size(), 0}).first;
    auto& target = segment_->slot(slot->second.index);
    if (fresh) {
      target.tx = t.tx;
      target.ty = t.ty;
    }
    // Seqlock write: odd, a release fence, the data, even with release (docs/shm.md). The counter is this
    // process's own, not whatever the mapping holds now.
    const auto sequence = slot->second.sequence;
    target.sequence.store(sequence + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    target.revision = values->revision;
    std::memcpy(reinterpret_cast<unsigned char*>(&target) + sizeof(layout::TileSlotHeader), values->values.data(),
                std::min<std::uint64_t>(values->values.size() * sizeof(float),
                                        segment_->layout().slot_bytes - sizeof(layout::TileSlotHeader)));
    target.sequence.store(sequence + 2, std::memory_order_release);
    slot->second.sequence = sequence + 2;
    if (fresh) header.tile_count.store(slots_.size(), std::memory_order_release);  // counted once whole
    slot->second.revision = values->revision;
  }

  if (map_changed) {
    // Objects and edges first when the map does not fit: the plan is bounded, the elements are what grows.
    const auto room = segment_->layout().map_capacity_bytes - sizeof(layout::MapHeader);
    const auto plan_bytes = object_count * sizeof(layout::ObjectRecord) + edge_count * sizeof(layout::EdgeRecord);
    const auto element_bytes = element_count * sizeof(layout::ElementRecord);
    bool map_truncated = false;
    if (plan_bytes + element_bytes > room) {
      map_truncated = true;
      const auto kept = plan_bytes <= room ? (room - plan_bytes) / sizeof(layout::ElementRecord) : 0;
      records.erase(records.begin() + static_cast<std::ptrdiff_t>(kept * sizeof(layout::ElementRecord)),
                    records.begin() + static_cast<std::ptrdiff_t>(element_bytes));
      element_count = kept;
      if (plan_bytes > room) {
        records.clear();
        object_count = edge_count = 0;
      }
    }
    write_map(records, state->version, element_count, object_count, edge_count);
    map_version_ = state->version;
    counts_.elements = element_count;
    counts_.objects = object_count;
    counts_.edges = edge_count;
    counts_.map_complete = !map_truncated;
  }
  counts_.tiles_complete = !tiles_truncated;
  header.truncated.store(
      (tiles_truncated ? layout::kTilesTruncated : 0) | (counts_.map_complete ? 0 : layout::kMapTruncated),
      std::memory_order_release);
  // Advances even when tiles were left out (the truncated bit says so), so that readers polling it see the changes
  // of the tiles that are there.
  grid_revision_ = static_cast<std::uint64_t>(tiles.revision);
  counts_.updated_unix_ns = unix_ns_now();
  header.grid_revision.store(grid_revision_, std::memory_order_release);
  header.updated_unix_ns.store(counts_.updated_unix_ns, std::memory_order_release);
  if (tiles_truncated || !counts_.map_complete)
    error_ = full_message(tiles_needed, map_bytes_needed_, size_cap());
  else
    error_.clear();
}

void SharedMapExport::write_map(const std::vector<unsigned char>& records, std::int64_t version, std::uint64_t elements,
                                std::uint64_t objects, std::uint64_t edges) {
  auto& map = segment_->map();
  const auto sequence = map_sequence_;
  map.sequence.store(sequence + 1, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  map.version = version;
  map.element_count = elements;
  map.object_count = objects;
  map.edge_count = edges;
  if (!records.empty())  // an empty vector's data() may be null, which memcpy must not get
    std::memcpy(reinterpret_cast<unsigned char*>(&map) + sizeof(layout::MapHeader), records.data(), records.size());
  map.sequence.store(sequence + 2, std::memory_order_release);
  map_sequence_ = sequence + 2;
}

std::uint64_t SharedMapExport::size_cap() const {
  // Half of what is free now: the new segment is reserved while the old one still holds its pages, and /dev/shm
  // stays usable by others.
  return std::min(options_.max_bytes, free_shm_bytes() / 2);
}

std::string SharedMapExport::full_message(std::uint64_t tiles, std::uint64_t map_bytes, std::uint64_t cap) const {
  const auto needed = layout::kHeaderBytes + tiles * layout::slot_bytes_for(tile_size_cells_) + map_bytes;
  return std::to_string(tiles) + " tiles and the map need " + std::to_string((needed + (1 << 20) - 1) >> 20) +
         " MB of shared memory; the cap is " + std::to_string(cap >> 20) +
         " MB (--shm-max-mb, half of /dev/shm's free space): what does not fit is left out" +
         (creation_error_.empty() ? "" : " (" + creation_error_ + ")");
}

bool SharedMapExport::grow(std::uint64_t tiles, std::uint64_t map_bytes, bool copy) {
  if (std::chrono::steady_clock::now() < retry_after_) return false;  // a creation failed a moment ago
  const auto slot_bytes = layout::slot_bytes_for(tile_size_cells_);
  const std::uint64_t old_tiles = segment_ ? segment_->layout().tile_capacity : 0;
  const std::uint64_t old_map = segment_ ? segment_->layout().map_capacity_bytes : 0;
  const auto cap = size_cap();
  // Twice what is needed, so that growing stays rare; when that does not fit, as large as the cap allows (never
  // less than now), so that a server near its cap does not make a new segment for each new tile. A replacement
  // (copy false) starts afresh and may be smaller than the segment it replaces.
  auto tile_capacity = std::max(2 * tiles, std::max<std::uint64_t>(1, kMinTileBytes / slot_bytes));
  auto map_capacity = round_up(std::max(2 * map_bytes, kMinMapBytes), kPage);
  const auto bytes_for = [&] { return layout::kHeaderBytes + tile_capacity * slot_bytes + map_capacity; };
  if (bytes_for() > cap) {
    const auto room = cap > layout::kHeaderBytes ? cap - layout::kHeaderBytes : 0;
    map_capacity = std::max(copy ? old_map : 0, round_up(std::max(map_bytes, kMinMapBytes), kPage));
    tile_capacity = room > map_capacity ? (room - map_capacity) / slot_bytes : 0;
    if (bytes_for() > cap ||
        (copy && (tile_capacity < old_tiles || (tile_capacity == old_tiles && map_capacity == old_map)))) {
      if (!segment_ || !copy) error_ = full_message(tiles, map_bytes, cap);
      return false;  // keep the segment there is; sync_locked flags what is left out
    }
  }

  const auto name = layout::kNamePrefix + boost::uuids::to_string(boost::uuids::random_generator()());
  // Computed once, here: the header written below tells readers, and nothing reads it back.
  Segment::Layout place;
  place.tile_size_cells = tile_size_cells_;
  place.bytes = bytes_for();
  place.tiles_offset = layout::kHeaderBytes;
  place.slot_bytes = slot_bytes;
  place.tile_capacity = tile_capacity;
  place.map_offset = layout::kHeaderBytes + tile_capacity * slot_bytes;
  place.map_capacity_bytes = map_capacity;
  std::unique_ptr<Segment> next;
  try {
    next = std::make_unique<Segment>(name, place);
  } catch (const std::exception& e) {
    creation_error_ =
        std::string("cannot make a shared memory segment of ") + std::to_string(bytes_for() >> 20) + " MB: " + e.what();
    error_ = creation_error_;
    retry_after_ = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    return false;  // keep the segment there is, and flag what is left out
  }
  creation_error_.clear();
  {
    const auto guard = next->guard();
    auto& header = *new (next->base()) layout::SegmentHeader{};
    std::memcpy(header.magic, layout::kMagic, sizeof header.magic);
    header.layout_version = layout::kLayoutVersion;
    header.header_bytes = layout::kHeaderBytes;
    header.owner_pid = ::getpid();
    header.owner_start_ticks = owner_start_ticks_;
    copy_text(header.server_instance, sizeof header.server_instance, server_instance_);
    header.tile_size_cells = tile_size_cells_;
    header.resolution_m = resolution_m_;
    header.layer_count = layout::kLayerCount;
    header.slot_bytes = place.slot_bytes;
    header.tiles_offset = place.tiles_offset;
    header.tile_capacity = place.tile_capacity;
    header.map_offset = place.map_offset;
    header.map_capacity_bytes = place.map_capacity_bytes;
    header.segment_bytes = place.bytes;
    new (next->base() + place.map_offset) layout::MapHeader{};
    if (segment_ && copy) {
      // Only this thread writes, so the old slots and map are whole and copy as they are; their headers are then
      // written again from this process's own bookkeeping, whatever the old mapping holds now.
      const auto old_guard = segment_->guard();
      const auto& old = segment_->layout();
      std::memcpy(next->base() + place.tiles_offset, segment_->base() + old.tiles_offset, slots_.size() * slot_bytes);
      std::memcpy(static_cast<void*>(&next->map()), &segment_->map(), std::min(old.map_capacity_bytes, map_capacity));
      for (const auto& [key, slot] : slots_) {
        auto& target = next->slot(slot.index);
        target.tx = key.first;
        target.ty = key.second;
        target.revision = slot.revision;
        target.sequence.store(slot.sequence, std::memory_order_relaxed);
      }
      auto& map = next->map();
      map.sequence.store(map_sequence_, std::memory_order_relaxed);
      map.version = map_version_;
      map.element_count = counts_.elements;
      map.object_count = counts_.objects;
      map.edge_count = counts_.edges;
      header.tile_count.store(slots_.size(), std::memory_order_relaxed);
      header.grid_revision.store(grid_revision_, std::memory_order_relaxed);
      header.truncated.store(
          (counts_.tiles_complete ? 0 : layout::kTilesTruncated) | (counts_.map_complete ? 0 : layout::kMapTruncated),
          std::memory_order_relaxed);
      header.updated_unix_ns.store(counts_.updated_unix_ns, std::memory_order_relaxed);
    }
    header.state.store(static_cast<std::uint32_t>(layout::SegmentState::live), std::memory_order_release);
  }
  if (next->lost() || (segment_ && copy && segment_->lost())) {
    next->unlink();  // shrunk while being made, or the copy came from a shrunk file
    return false;
  }
  if (!copy) {
    map_sequence_ = 0;
    for (auto& [key, slot] : slots_) slot.sequence = 0;
  }
  if (segment_) {
    {
      const auto old_guard = segment_->guard();
      copy_text(segment_->header().successor, sizeof segment_->header().successor, name);
      segment_->header().state.store(static_cast<std::uint32_t>(layout::SegmentState::retired),
                                     std::memory_order_release);
    }
    segment_->unlink();
  }
  segment_ = std::move(next);
  ++generation_;
  return true;
}

ShmStatus SharedMapExport::status() const {
  std::lock_guard lock(mutex_);
  ShmStatus status = counts_;
  status.period = options_.period;
  status.generation = generation_;
  status.tile_size_cells = tile_size_cells_;
  status.resolution_m = resolution_m_;
  status.map_version = map_version_;
  if (!segment_) {
    status.error = error_.empty() ? "the segment has not been made yet" : error_;
    return status;
  }
  // All from this process's own bookkeeping: the mapping may have been rewritten or cut short.
  const auto& place = segment_->layout();
  status.available = true;
  status.error = error_;
  status.name = segment_->name();
  status.bytes = place.bytes;
  status.owner_pid = ::getpid();
  status.tiles_offset = place.tiles_offset;
  status.slot_bytes = place.slot_bytes;
  status.tile_capacity = place.tile_capacity;
  status.tile_count = slots_.size();
  status.map_offset = place.map_offset;
  status.map_capacity_bytes = place.map_capacity_bytes;
  status.grid_revision = grid_revision_;
  return status;
}

}  // namespace wm::shm
