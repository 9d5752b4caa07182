#pragma once

// The whole map as JSON text, each element's and object's text kept from the build before when its updated_version
// has not moved: under ingest a new map version changes a few elements of thousands, and serialising all of them
// again was most of the cost of a full map read.
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "server/world/world_state.h"

namespace wm::api {

class MapJsonWriter {
 public:
  /// The same bytes as json_codec::map_json(state, options) with "server_instance" set, dumped compactly (keys in
  /// nlohmann's order), so that a client cannot tell the two apart. Safe from any thread (one build at a time).
  std::string write(const world::WorldState& state, const world::WorldOptions& options, const std::string& instance);

 private:
  struct Fragment {
    std::int64_t updated_version = -1;
    const void* identity = nullptr;  // the object's drawing (objects only): a new plan is a new object
    std::string text;
  };
  std::mutex mutex_;
  std::map<std::int64_t, Fragment> elements_;  // by number
  std::vector<Fragment> objects_;              // by index in the plan
};

}  // namespace wm::api
