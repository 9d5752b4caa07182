#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <set>
#include <string>

#include "common/diagnostics.h"
#include "rules/engine.h"
#include "server/service/event_log.h"
#include "server/service/snapshot_log.h"
#include "server/service/world_port.h"
#include "server/world/update.h"

namespace wm::service {

struct MapWriterOptions {
  world::WorldOptions world;
  /// Decisions the knowledge base keeps as decision/7 facts (the full log is in SQLite).
  std::size_t decision_facts_kept = 10000;
  /// At most this many elements pruned per update.
  std::size_t max_prune_per_update = 1000;
};

/// An observation decided and applied in memory (the rules' facts already follow it), not yet committed.
struct PreparedUpdate {
  std::shared_ptr<const world::WorldState> base;  // the state it was decided against
  world::Observation observation;
  world::UpdateResult update;
  std::int64_t seq = 0;
};

/// One observation's way into the map, in three steps that the caller runs on the writer thread with its own store
/// write between them: prepare (decide against a base map; the knowledge base's facts follow the decided map),
/// commit (the caller's store write; when it throws, the facts go back to the base), finish (publish the new map,
/// log the decisions as facts, add the update event to the commit's events). It owns the published map.
class MapWriter {
 public:
  /// `initial`: the map as the store loaded it. `engine` and `diagnostics` must outlive the writer.
  MapWriter(const MapWriterOptions& options, world::WorldState initial, rules::Engine& engine,
            common::Diagnostics& diagnostics);

  const MapWriterOptions& options() const { return options_; }
  /// The committed map, as readers see it.
  std::shared_ptr<const world::WorldState> snapshot() const { return published_.current(); }
  SnapshotLog& published() { return published_; }
  const SnapshotLog& published() const { return published_; }

  /// Decides `observation` against `base` with the rules, numbered next after it. @throw from the rules or the
  /// update (the facts are back at `base` then).
  PreparedUpdate prepare(std::shared_ptr<const world::WorldState> base, world::Observation observation);
  /// An observation the server makes itself (grid trim, placement, redecide) against `base`, numbered next; its
  /// update is the caller's to fill.
  static PreparedUpdate own_observation(std::shared_ptr<const world::WorldState> base, std::string observer,
                                        std::string origin, std::string sensor);
  /// The knowledge base's element facts follow `update`: its changed elements, and (`removals`) those it removed.
  /// Part of a prepare, on the writer; the caller puts the facts back if the prepare fails.
  void follow_elements(const world::UpdateResult& update, bool removals);
  /// The rules' prune/3 over the map as `p` leaves it (the facts must follow it): applies their orders to `p`, at
  /// most MapWriterOptions::max_prune_per_update, as decisions of `observer`, and drops the pruned elements' facts.
  void prune(PreparedUpdate& p, const std::string& observer);
  /// Runs `store_write`; if it throws, puts the rules' facts back to the committed map and rethrows.
  void commit(const PreparedUpdate& prepared, const std::function<void()>& store_write);
  /// After the commit: publishes the new map (with `removed_objects`, the plan objects it no longer has), logs the
  /// decisions as facts and adds the update event to `live`.
  PrimitivesOutcome finish(PreparedUpdate prepared, EventLog::Commit& live, std::set<std::string> removed_objects = {});
  /// Replaces every plan and element fact with those of `state` (after a failure: the map as committed); a failure
  /// here is reported, not thrown, naming `after`.
  void restore_facts(const world::WorldState& state, const std::string& after);

 private:
  const MapWriterOptions options_;
  rules::Engine& engine_;
  common::Diagnostics& diagnostics_;
  SnapshotLog published_;
};

/// Now, in seconds since the Unix epoch (when an observation was received).
double now_unix_s();

}  // namespace wm::service
