// read_grid: prints what a wmd shared-memory segment holds, using the header-only reader.
//
//   read_grid wm-<uuid> [--watch]
//
// The name comes from GET /api/v1/shm ("name"). With --watch it polls, prints a line whenever grid_revision or the
// map version changes, follows the successor when the server moves to a larger segment (state retired), and exits
// when the server stops cleanly (state stopped).
//
// The server unlinks a retired segment's name at once: a reader that missed two growths (A -> B -> C while it
// still maps A) finds B gone too. A client that knows the server's URL asks GET /api/v1/shm again then; this
// example knows only a name, so it says so and exits 1.
//
// Build: g++ -std=c++17 -O2 -I<repo> clients/shm/examples/read_grid.cpp -o read_grid
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <optional>
#include <string>
#include <thread>

#include "wire/shm/worldmodel_shm.h"

namespace {

namespace shm = worldmodel::shm;

const char* state_name(shm::SegmentState state) {
  switch (state) {
    case shm::SegmentState::live:
      return "live";
    case shm::SegmentState::retired:
      return "retired";
    case shm::SegmentState::stopped:
      return "stopped";
  }
  return "unknown";
}

// One line: what the segment holds now. Returns the map version, to tell a change when watching.
std::int64_t print_summary(const shm::Reader& reader) {
  const auto dense = reader.read_layer(shm::Layer::bayes);
  std::size_t known = 0, occupied = 0;
  for (const float p : dense.values) {
    if (std::isnan(p)) continue;
    ++known;
    if (p > 0.65f) ++occupied;
  }
  const auto map = reader.read_map();
  const auto truncated = reader.header().truncated.load(std::memory_order_relaxed);
  std::printf(
      "%s [%s] revision %llu: %lld x %lld cells at %.3f m, origin (%lld, %lld) cells, %zu tiles, %zu known, "
      "%zu occupied; map version %lld: %zu elements, %zu objects, %zu edges%s%s\n",
      reader.name().c_str(), state_name(reader.state()), static_cast<unsigned long long>(dense.grid_revision),
      static_cast<long long>(dense.width), static_cast<long long>(dense.height), dense.resolution_m,
      static_cast<long long>(dense.x0_cells), static_cast<long long>(dense.y0_cells), reader.tile_count(), known,
      occupied, static_cast<long long>(map.version), map.elements.size(), map.objects.size(), map.edges.size(),
      (truncated & shm::kTilesTruncated) != 0 ? " (tiles truncated)" : "",
      (truncated & shm::kMapTruncated) != 0 ? " (map truncated)" : "");
  std::fflush(stdout);
  return map.version;
}

int watch(shm::Reader reader) {
  std::uint64_t revision = reader.grid_revision();
  std::int64_t map_version = print_summary(reader);
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const auto state = reader.state();
    if (state == shm::SegmentState::stopped) {
      print_summary(reader);  // the server's last state
      std::printf("%s: the server stopped\n", reader.name().c_str());
      return 0;
    }
    if (state == shm::SegmentState::retired) {
      const auto next = reader.successor();
      std::printf("%s: retired, following %s\n", reader.name().c_str(), next ? next->c_str() : "(none)");
      std::fflush(stdout);
      try {
        if (!next || next->empty()) throw shm::Error("it names no successor");
        reader = shm::Reader(*next);  // the old mapping stays valid until here, even though its name is gone
      } catch (const shm::Error& error) {
        std::fprintf(stderr,
                     "read_grid: cannot follow %s: %s\n"
                     "read_grid: the server has moved on since (it grew the segment again, or stopped): ask GET "
                     "/api/v1/shm for the current name and start again\n",
                     reader.name().c_str(), error.what());
        return 1;
      }
      revision = reader.grid_revision();
      map_version = print_summary(reader);
      continue;
    }
    const auto now = reader.grid_revision();
    const auto version = reader.map_version();  // the version alone, under the seqlock: no copy of the map
    if (now != revision || version != map_version) {
      revision = now;
      map_version = print_summary(reader);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string name;
  bool watching = false;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--watch") == 0) {
      watching = true;
    } else if (name.empty() && argv[i][0] != '-') {
      name = argv[i];
    } else {
      name.clear();
      break;
    }
  }
  if (name.empty()) {
    std::fprintf(stderr, "usage: %s wm-<uuid> [--watch]   (the name from GET /api/v1/shm)\n", argv[0]);
    return 2;
  }
  std::optional<shm::Reader> reader;
  try {
    reader.emplace(name);
  } catch (const shm::Error& error) {  // e.g. the name is gone: the server grew the segment or stopped since
    std::fprintf(stderr, "read_grid: %s\nread_grid: ask GET /api/v1/shm for the current name\n", error.what());
    return 1;
  }
  try {
    if (watching) return watch(std::move(*reader));
    print_summary(*reader);
    return 0;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "read_grid: %s\n", error.what());
    return 1;
  }
}
