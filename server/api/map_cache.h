#pragma once

// The map as bytes, made at most once per published version: GET /api/v1/map serves the same text to every client
// that asks for that version (and its gzip form to those that accept it), instead of serialising the snapshot again
// for each request. A client that accepts a slightly older map (Cache-Control: max-stale) is answered at once from
// the last body while a background thread makes the next one: under full-rate ingest every request would otherwise
// find a new version and wait for its serialisation.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "server/api/map_json_writer.h"
#include "server/world/world_state.h"

namespace wm::api {

/// One representation of one map version.
struct MapBody {
  std::int64_t version = 0;
  std::chrono::steady_clock::time_point taken;  // when its snapshot was read: the body shows the map as of then
  std::string content_type;
  std::string bytes;
  /// The gzip form of `bytes`, made on first demand (see MapCache::gzip_of).
  mutable std::shared_ptr<const std::string> gzip;
  mutable std::once_flag gzip_once;
  mutable std::atomic<bool> gzip_made{false};  // set once `gzip` is there (gzip_if_made reads it without the flag)
};

class MapCache {
 public:
  MapCache();
  ~MapCache();  // waits for a background build under way
  MapCache(const MapCache&) = delete;
  MapCache& operator=(const MapCache&) = delete;

  /// A random token drawn at start, part of every ETag: a version number names another map after the database
  /// was replaced, so tags from before a restart never match.
  const std::string& instance() const { return instance_; }
  /// The whole map's JSON writer, which keeps each element's text between versions (for builds of format json).
  MapJsonWriter& json_writer() { return json_writer_; }

  /// Makes the bytes of a snapshot. Kept for a background build: must not refer to a request's objects.
  using Build = std::function<std::string(const world::WorldState&)>;

  /// The body of `format` for `snapshot`, built with `build` by the first request that needs it; requests that
  /// ask meanwhile wait for that build rather than repeat it; one build runs at a time, on `latest()` when given.
  /// Never older than `snapshot` (a newer body is served), unless `max_stale` allows: then the last body is served
  /// at once when its snapshot was read at most `max_stale` ago, and the current snapshot is built in the
  /// background.
  /// The newest published snapshot (what a build started now should show).
  using Latest = std::function<std::shared_ptr<const world::WorldState>()>;

  /// `at_once`: never wait nor build on the caller's thread (an I/O thread): nullptr when the body is not there
  /// yet (a stale one is still served as max_stale allows, its successor queued for the background builder).
  std::shared_ptr<const MapBody> body(const std::shared_ptr<const world::WorldState>& snapshot,
                                      const std::string& format, const std::string& content_type, const Build& build,
                                      std::chrono::milliseconds max_stale = std::chrono::milliseconds(0),
                                      const Latest& latest = {}, bool at_once = false);

  /// The answer to ?since=`since` for `snapshot`, made once per (since, version): polling clients that hold the same
  /// version ask the same question, and those that ask while it is made wait for it (an answer for a newer version
  /// serves them too). At most kDeltasKept answers and kDeltaBytesKept bytes are kept, the oldest versions going
  /// first. `build` may throw (410): nothing is kept then.
  std::shared_ptr<const MapBody> delta(const std::shared_ptr<const world::WorldState>& snapshot, std::int64_t since,
                                       const Build& build, bool at_once = false);

  /// The gzip bytes of `body` (level 6), compressed once. @throw std::runtime_error when zlib fails.
  static std::shared_ptr<const std::string> gzip_of(const MapBody& body);
  /// The gzip bytes when gzip_of has made them, else nullptr (never compresses).
  static std::shared_ptr<const std::string> gzip_if_made(const MapBody& body);

 private:
  struct Slot {
    std::shared_ptr<const MapBody> done;
    std::int64_t building = -1;  // the version being built (by a request or in the background), -1 when none
  };
  struct Job {
    std::shared_ptr<const world::WorldState> snapshot;
    std::string content_type;
    Build build;
    std::chrono::steady_clock::time_point taken;  // when the request read the snapshot
  };
  // Builds `job` for `slot` (mutex_ held on entry and on return; released while building) and keeps the result
  // unless a newer body is there by then.
  std::shared_ptr<const MapBody> build_into(Slot& slot, const Job& job, std::unique_lock<std::mutex>& lock);
  void run_background_builds();

  std::string instance_;
  MapJsonWriter json_writer_;
  std::mutex mutex_;
  std::condition_variable built_;
  std::map<std::string, Slot> slots_;   // by format
  std::map<std::string, Job> pending_;  // the newest snapshot to build in the background, by format
  static constexpr std::size_t kDeltasKept = 64;
  static constexpr std::size_t kDeltaBytesKept = 32u << 20;
  std::map<std::int64_t, Slot> deltas_;  // by since
  std::condition_variable work_;
  bool stopping_ = false;
  std::thread builder_;  // started on the first background build
};

}  // namespace wm::api
