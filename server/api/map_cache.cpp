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

MapCache::~MapCache() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  work_.notify_all();
  if (builder_.joinable()) builder_.join();
}

std::shared_ptr<const MapBody> MapCache::body(const std::shared_ptr<const world::WorldState>& snapshot,
                                              const std::string& format, const std::string& content_type,
                                              const Build& build, std::chrono::milliseconds max_stale,
                                              const Latest& latest, bool at_once) {
  const auto version = snapshot->version;
  const auto now = std::chrono::steady_clock::now();
  std::unique_lock lock(mutex_);
  auto& slot = slots_[format];
  if (max_stale.count() > 0 && slot.done && slot.done->version < version && now - slot.done->taken <= max_stale) {
    if (slot.building < version) {
      auto& job = pending_[format];
      if (!job.snapshot || job.snapshot->version < version) job = Job{snapshot, content_type, build, now};
      if (!builder_.joinable()) builder_ = std::thread([this] { run_background_builds(); });
      work_.notify_one();
    }
    return slot.done;
  }
  for (;;) {
    if (slot.done && slot.done->version >= version) return slot.done;
    if (at_once) return nullptr;
    if (slot.building < 0) break;
    // One build at a time: a build of an older version under way is waited for too, and the next one then takes
    // the newest snapshot, so it serves every request that came meanwhile (under ingest each request finds a
    // newer version, and builds of their own would only share the cores).
    built_.wait(lock);
  }
  auto newest = latest ? latest() : snapshot;
  if (!newest || newest->version < version) newest = snapshot;
  return build_into(slot, Job{newest, content_type, build, now}, lock);
}

std::shared_ptr<const MapBody> MapCache::build_into(Slot& slot, const Job& job, std::unique_lock<std::mutex>& lock) {
  const auto version = job.snapshot->version;
  // Waiters for this version wait for this build; an older build under way is kept only if nothing newer is there.
  slot.building = version;
  lock.unlock();
  std::shared_ptr<MapBody> made;
  try {
    made = std::make_shared<MapBody>();
    made->version = version;
    made->taken = job.taken;
    made->content_type = job.content_type;
    made->bytes = job.build(*job.snapshot);
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

void MapCache::run_background_builds() {
  std::unique_lock lock(mutex_);
  for (;;) {
    work_.wait(lock, [this] { return stopping_ || !pending_.empty(); });
    if (stopping_) return;
    auto next = pending_.begin();
    const auto format = next->first;
    const Job job = std::move(next->second);
    pending_.erase(next);
    auto& slot = slots_[format];
    const auto version = job.snapshot->version;
    if ((slot.done && slot.done->version >= version) || slot.building >= version) continue;
    try {
      build_into(slot, job, lock);
    } catch (...) {
      // The next request that cannot take a stale body builds it again in its own path and reports the error.
    }
  }
}

std::shared_ptr<const MapBody> MapCache::delta(const std::shared_ptr<const world::WorldState>& snapshot,
                                               std::int64_t since, const Build& build, bool at_once) {
  const auto version = snapshot->version;
  const auto now = std::chrono::steady_clock::now();
  std::unique_lock lock(mutex_);
  auto& slot = deltas_[since];
  for (;;) {
    if (slot.done && slot.done->version >= version) return slot.done;
    if (at_once) {
      if (!slot.done && slot.building < 0) deltas_.erase(since);  // asked, not made: no empty slot left behind
      return nullptr;
    }
    if (slot.building < version) break;
    built_.wait(lock);  // the answer for this version or a newer one is being made
  }
  auto made = build_into(slot, Job{snapshot, "application/json", build, now}, lock);
  // The answers for the oldest versions go first: their clients have moved on. Slots being built stay (a builder
  // holds them).
  const auto kept_bytes = [this] {
    std::size_t bytes = 0;
    for (const auto& [key, kept] : deltas_)
      if (kept.done) bytes += kept.done->bytes.size();
    return bytes;
  };
  while (deltas_.size() > kDeltasKept || kept_bytes() > kDeltaBytesKept) {
    auto oldest = deltas_.end();
    for (auto it = deltas_.begin(); it != deltas_.end(); ++it) {
      if (it->second.building >= 0 || it->first == since) continue;
      const auto age = it->second.done ? it->second.done->version : -1;
      if (oldest == deltas_.end() || age < (oldest->second.done ? oldest->second.done->version : -1)) oldest = it;
    }
    if (oldest == deltas_.end()) break;
    deltas_.erase(oldest);
  }
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
    body.gzip_made.store(true, std::memory_order_release);
  });
  return body.gzip;
}

std::shared_ptr<const std::string> MapCache::gzip_if_made(const MapBody& body) {
  return body.gzip_made.load(std::memory_order_acquire) ? body.gzip : nullptr;
}

}  // namespace wm::api
