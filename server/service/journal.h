#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>

#include "server/json/codec.h"
#include "server/storage/store.h"
#include "server/world/scan_observation.h"

namespace wm::service {

/// A journaled scan; rows stored before the journal kept scans in binary form hold the request body instead.
/// @throw json_codec::CodecError for such a body this build does not read.
inline world::ScanObservation journaled_scan(storage::JournaledScan&& record) {
  if (record.scan) return std::move(*record.scan);
  return json_codec::parse_scan(record.legacy_json, json_codec::ScanLimits{});
}

/// Calls `visit(seq, scan record)` for every journaled scan past `after`, in order, reading a page at a time.
template <typename Visit>
void for_each_journaled_scan(storage::Store& store, std::int64_t after, Visit visit) {
  constexpr std::size_t kPage = 256;
  for (;;) {
    auto page = store.scans_after(after, kPage);
    for (auto& record : page) {
      after = record.seq;
      visit(record.seq, std::move(record));
    }
    if (page.size() < kPage) return;
  }
}

}  // namespace wm::service
