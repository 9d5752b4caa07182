#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <thread>

#include "rules/engine.h"
#include "server/storage/store.h"
#include "server/world/update.h"

namespace wm::service {

/// The writer queue is full: the caller should answer 503 and the client retry later.
class Busy : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ServiceOptions {
  world::WorldOptions world;
  std::size_t max_queued_requests = 256;
};

/// Owns the world model. One writer thread applies every change (match → rules → apply → store) in
/// arrival order; readers take immutable snapshots that are swapped after each committed request, so
/// they never block the writer and never see half an update. Prolog decisions run on the writer thread.
class WorldService {
 public:
  /// Starts the writer with the state loaded from `store`. @throw storage::StorageError, rules::RuleError.
  WorldService(const ServiceOptions& options, storage::Store& store, rules::Engine& engine);
  ~WorldService();
  WorldService(const WorldService&) = delete;
  WorldService& operator=(const WorldService&) = delete;

  std::shared_ptr<const world::WorldState> snapshot() const;
  const ServiceOptions& options() const { return options_; }
  storage::Store& store() { return store_; }

  struct PrimitivesOutcome {
    std::int64_t seq = 0;
    std::int64_t version = 0;
    std::vector<world::DecisionRecord> decisions;
  };
  /// Applies one request whole or not at all, and returns after it is committed.
  /// @throw Busy, storage::StorageError, std::exception from the update (nothing applied then).
  PrimitivesOutcome post_primitives(world::Observation observation, std::string payload_json);
  /// Replaces the floor plan (store and knowledge base facts). Returns the new map version.
  std::int64_t load_floor_plan(apriori::FloorPlan plan);
  rules::RulesStatus rules_status();

 private:
  template <typename F>
  auto run_on_writer(F&& work) -> decltype(work());
  void writer_loop();
  void publish(world::WorldState state);
  std::vector<rules::ObjectFacts> facts(const world::WorldState& state) const;

  const ServiceOptions options_;
  storage::Store& store_;
  rules::Engine& engine_;

  mutable std::mutex snapshot_mutex_;
  std::shared_ptr<const world::WorldState> snapshot_;

  std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;
  std::thread writer_;
};

}  // namespace wm::service
