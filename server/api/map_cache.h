#pragma once

// The map as bytes, made at most once per published version: GET /api/v1/map serves the same text to every client
// that asks for that version (and its gzip form to those that accept it), instead of serialising the snapshot again
// for each request.
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "server/world/world_state.h"

namespace wm::api {

/// One representation of one map version.
struct MapBody {
  std::int64_t version = 0;
  std::string content_type;
  std::string bytes;
  /// The gzip form of `bytes`, made on first demand (see MapCache::gzip_of).
  mutable std::shared_ptr<const std::string> gzip;
  mutable std::once_flag gzip_once;
};

class MapCache {
 public:
  MapCache();

  /// A random token drawn at start, part of every ETag: a version number names another map after the database
  /// was replaced, so tags from before a restart never match.
  const std::string& instance() const { return instance_; }

  using Build = std::function<std::string(const world::WorldState&)>;

  /// The body of `format` for `snapshot`, built with `build` by the first request that needs it; requests that
  /// ask meanwhile wait for that build rather than repeat it. Never older than `snapshot`: when a build of a newer
  /// version is under way or done, its body is served.
  std::shared_ptr<const MapBody> body(const std::shared_ptr<const world::WorldState>& snapshot, const std::string& format,
                                      const std::string& content_type, const Build& build);

  /// The gzip bytes of `body` (level 6), compressed once. @throw std::runtime_error when zlib fails.
  static std::shared_ptr<const std::string> gzip_of(const MapBody& body);

 private:
  struct Slot {
    std::shared_ptr<const MapBody> done;
    std::int64_t building = -1;  // the version a request is building, -1 when none
  };
  std::string instance_;
  mutable std::mutex mutex_;
  std::condition_variable built_;
  std::map<std::string, Slot> slots_;  // by format
};

}  // namespace wm::api
