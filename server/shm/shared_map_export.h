#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/diagnostics.h"
#include "server/events/event_hub.h"
#include "server/service/world_port.h"

namespace wm::shm {

struct ShmOptions {
  bool enabled = true;
  /// How often the exporter looks for changed tiles and a new map version: a reader sees a change this late at most
  /// (plus the copy), while the copies take less than a tenth of it; under heavier ingest the pause grows to nine
  /// times the last pass, so the export never takes more than a tenth of a core from ingest. [1 ms, 10 s]
  std::chrono::milliseconds period{20};
  /// With the event hub, a pass this long after the last at the latest, should an event ever be missed.
  std::chrono::milliseconds idle_period{1000};
  /// The segment never grows past this, nor past half of /dev/shm's free space when it is made (containers often
  /// give /dev/shm 64 MB). What does not fit is left out and flagged (truncated).
  std::uint64_t max_bytes = std::uint64_t{1} << 30;
};

/// What GET /api/v1/shm reports.
struct ShmStatus {
  bool available = false;
  std::string error;  // why not, when not available
  std::string name;   // "wm-<uuid>"
  std::uint64_t bytes = 0;
  std::uint64_t generation = 0;  // segments made so far in this run (a larger one replaces a full one)
  std::int64_t owner_pid = 0;
  std::int64_t tile_size_cells = 0;
  double resolution_m = 0;
  std::uint64_t tiles_offset = 0;
  std::uint64_t slot_bytes = 0;
  std::uint64_t tile_capacity = 0;
  std::uint64_t tile_count = 0;
  bool tiles_complete = true;
  std::uint64_t map_offset = 0;
  std::uint64_t map_capacity_bytes = 0;
  std::int64_t map_version = -1;  // -1 until the first pass wrote the map
  std::uint64_t elements = 0;
  std::uint64_t objects = 0;
  std::uint64_t edges = 0;
  bool map_complete = true;
  std::uint64_t grid_revision = 0;
  std::int64_t updated_unix_ns = 0;
  std::chrono::milliseconds period{0};
};

/// Keeps the grid layers and the vector map in a POSIX shared-memory segment (Boost.Interprocess) for processes on
/// the same machine, which read them without HTTP or JSON (wire/shm/worldmodel_shm.h holds the layout and a
/// reader; docs/shm.md the protocol).
///
/// A thread of its own looks at the service every `period` (or nine times its last pass, whichever is longer; with the
/// event hub only once something changed): the tiles
/// whose revision changed are copied in (each under its slot's sequence counter, a seqlock), and so is the map when its
/// version changed. Ingest never waits for it beyond the grid's shared lock for one tile's copy, and never for a
/// reader.
///
/// The segment is named "wm-<uuid>". When a slot or the map does not fit, a segment twice the size replaces it: the
/// old one is marked retired with the new name in it, then unlinked (mapped readers keep their memory). At
/// destruction the segment is marked stopped and unlinked. At construction, segments left by dead wmd processes
/// (no one holds their lock) are removed.
/// What the export reads: the map's snapshot and the grid's tiles.
struct ExportSource {
  const service::MapPort& map;
  const service::GridPort& grid;
  ExportSource(const service::WorldPort& world)  // NOLINT(google-explicit-constructor): both ports of one service
      : map(world), grid(world) {}
  ExportSource(const service::MapPort& m, const service::GridPort& g) : map(m), grid(g) {}
};

class SharedMapExport {
 public:
  /// Removes stale segments, makes the segment, fills it once and starts the thread. Never throws for a segment
  /// that cannot be made: status() says why, each pass tries again, and `diagnostics` (where "shm", which must
  /// outlive this) counts each new failure and each segment replaced.
  /// With `events` (which must outlive this), a pass runs only after an event (a scan in the grid, a commit, a
  /// plan moved), at most every `period`, and at the latest `idle_period` after the last one: an idle server
  /// costs next to nothing. Without, every `period`.
  SharedMapExport(ExportSource world, ShmOptions options, std::string server_instance, common::Diagnostics& diagnostics,
                  events::EventHub* events = nullptr);
  ~SharedMapExport();
  SharedMapExport(const SharedMapExport&) = delete;
  SharedMapExport& operator=(const SharedMapExport&) = delete;

  ShmStatus status() const;
  /// One pass now, on the caller's thread (waits for a running pass).
  void sync();

  /// Removes every "wm-<uuid>" segment in /dev/shm that is this user's regular file and whose lock no process holds
  /// (each server holds a shared flock on its segment while it runs; the kernel drops it when the process ends,
  /// kill -9 included), unless it has no header yet and is younger than a minute. Returns the names removed.
  static std::vector<std::string> remove_stale_segments();

 private:
  class Segment;
  struct Slot {
    std::uint64_t index = 0;
    std::uint64_t revision = 0;
    std::uint64_t sequence = 0;  // its seqlock counter as last written (even)
  };

  void run();
  void sync_locked();
  /// Replaces the segment by one with room for `tiles` slots and `map_bytes` of map, within the size cap, and
  /// retires the old one. With `copy`, the old slots and map are copied over; without (the old one was damaged),
  /// the new one starts empty and the caller fills it. False when that much does not fit, or the new segment was
  /// shrunk while being made (the segment stays).
  bool grow(std::uint64_t tiles, std::uint64_t map_bytes, bool copy);
  /// The largest segment allowed now [bytes].
  std::uint64_t size_cap() const;
  std::string full_message(std::uint64_t tiles, std::uint64_t map_bytes, std::uint64_t cap) const;
  void write_map(const std::vector<unsigned char>& records, std::int64_t version, std::uint64_t elements,
                 std::uint64_t objects, std::uint64_t edges);

  ExportSource world_;
  common::Diagnostics& diagnostics_;
  const ShmOptions options_;
  const std::string server_instance_;
  std::int64_t tile_size_cells_ = 0;
  double resolution_m_ = 0;

  mutable std::mutex mutex_;  // the segment and the bookkeeping below; one pass at a time
  std::unique_ptr<Segment> segment_;
  std::map<std::pair<std::int64_t, std::int64_t>, Slot> slots_;
  std::int64_t map_version_ = -1;
  std::uint64_t map_sequence_ = 0;  // the map's seqlock counter as last written
  std::uint64_t grid_revision_ = 0;
  std::uint64_t map_bytes_needed_ = 0;
  ShmStatus counts_;  // elements/objects/edges/truncation/update time of the last pass
  std::uint64_t generation_ = 0;
  std::string error_;
  std::string creation_error_;  // why the last segment could not be made ("" after one was)
  std::chrono::steady_clock::time_point retry_after_{};
  std::uint64_t owner_start_ticks_ = 0;

  std::mutex wake_mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  bool changed_ = false;  // an event came since the last pass (with a hub)
  events::EventHub* events_ = nullptr;
  std::shared_ptr<events::EventHub::Subscriber> subscriber_;
  std::thread thread_;
};

}  // namespace wm::shm
