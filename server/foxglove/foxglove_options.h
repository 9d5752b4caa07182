#pragma once

// What the Foxglove WebSocket is configured with. Header-only and free of dependencies (wm::foxglove_options), so
// that wmd's configuration (in wm::server) can hold it while the Foxglove library itself builds on wm::server.
#include <chrono>
#include <cstddef>

namespace wm::foxglove {

/// Limits of the Foxglove bridge (server/foxglove/bridge.h), validated by server/config/.
struct FoxgloveOptions {
  /// Changes (scene updates, decisions) one client may have queued and not yet written to its socket [bytes]. Past it
  /// (or past max_queued_messages) the client's queued messages are dropped and it is brought up to the current state
  /// once it reads again: a slow client costs memory up to this bound and never slows anyone else. Whole-state
  /// messages (the grid, poses, transforms) are not counted: a newer one replaces a queued one, and they share their
  /// bytes with the bridge.
  std::size_t max_queued_bytes = std::size_t{32} << 20;
  std::size_t max_queued_messages = 4096;
  /// The grid is sent at most once per this period, and only when its revision moved; the last change is always
  /// sent once the period is over (2 Hz: a grid message is megabytes of base64 on a large map).
  std::chrono::milliseconds grid_period{500};
  /// The scenes, robot poses, transforms and decisions are sent at most once per this period (changes batched).
  std::chrono::milliseconds update_period{100};
  /// Decisions a new subscriber of the decision log gets at once (the most recent ones).
  std::size_t initial_decisions = 100;
  /// Largest grid sent at the grid's own resolution [cells]; a larger one is sent coarser, each cell the largest value
  /// of a k × k block (an occupied cell stays visible), k the smallest integer that brings it under this bound.
  std::size_t max_grid_cells = 4'000'000;
  /// Clients served at once; one more is told so in a status and its connection closed (1013, try again later).
  /// Each holds up to its queue bound, and one that stopped reading keeps the grid it was last sent.
  std::size_t max_clients = 32;
};

}  // namespace wm::foxglove
