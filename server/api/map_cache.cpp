#include "server/api/map_cache.h"

#include <zlib.h>

#include <cstdio>
#include <random>
#include <stdexcept>

namespace wm::api {

MapCache::MapCache() {
  std::random_device random;
  char text[17];
  std::snprintf(text, sizeof text, "%08x%08x", random(), random());
  instance_ = text;
}

std::shared_ptr<const MapBody> MapCache::body(const std::shared_ptr<const world::WorldState>& snapshot,
                                              const std::string& format, const std::string& content_type,
                                              const Build& build) {
  const auto version = snapshot->version;
  std::unique_lock lock(mutex_);
  auto& slot = slots_[format];
  for (;;) {
    if (slot.done && slot.done->version >= version) return slot.done;
    if (slot.building < version) break;
    built_.wait(lock);  // a build of this version or a newer one is under way
  }
  // Build this version. A build already under way for an older version finishes and is kept only if nothing newer
  // is there by then; waiters for this version wait for this build.
  slot.building = version;
  lock.unlock();
  std::shared_ptr<MapBody> made;
  try {
    made = std::make_shared<MapBody>();
    made->version = version;
    made->content_type = content_type;
    made->bytes = build(*snapshot);
  } catch (...) {
    lock.lock();
    if (slot.building == version) slot.building = -1;
    built_.notify_all();
    throw;
  }
  lock.lock();
  if (!slot.done || slot.done->version < version) slot.done = made;
  if (slot.building == version) slot.building = -1;
  built_.notify_all();
  return made;
}

std::shared_ptr<const std::string> MapCache::gzip_of(const MapBody& body) {
  std::call_once(body.gzip_once, [&body] {
    z_stream stream{};
    // windowBits 15 + 16: a gzip header and trailer rather than zlib's.
    if (deflateInit2(&stream, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
      throw std::runtime_error("gzip: deflateInit2 failed");
    std::string out(deflateBound(&stream, static_cast<uLong>(body.bytes.size())) + 32, '\0');
    stream.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(body.bytes.data()));
    stream.avail_in = static_cast<uInt>(body.bytes.size());
    stream.next_out = reinterpret_cast<Bytef*>(out.data());
    stream.avail_out = static_cast<uInt>(out.size());
    const int rc = deflate(&stream, Z_FINISH);
    const auto written = stream.total_out;
    deflateEnd(&stream);
    if (rc != Z_STREAM_END) throw std::runtime_error("gzip: deflate did not finish");
    out.resize(written);
    body.gzip = std::make_shared<const std::string>(std::move(out));
  });
  return body.gzip;
}

}  // namespace wm::api
