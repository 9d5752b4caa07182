#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "apriori/floor_plan.h"
#include "rules/engine.h"
#include "server/service/event_log.h"
#include "server/service/grid_store.h"
#include "server/service/ingest_pipeline.h"
#include "server/service/map_writer.h"
#include "server/service/plan_checks.h"
#include "server/service/world_port.h"
#include "server/storage/store.h"
#include "server/world/plan_evidence.h"
#include "server/world/update.h"

namespace wm::service {

/// The parts of one map that the plan commands change; all must outlive them.
struct PlanParts {
  const MapWriterOptions& options;
  storage::Store& store;
  rules::Engine& engine;
  MapWriter& writer;
  GridStore& grid;
  PlanChecks& plan_checks;
  EventLog& events;
  IngestPipeline& ingest;  // its writer thread runs the commands
};

/// The commands that change a map's floor plan or how the map relates to it: load a plan, place it (undo, align to
/// the grid), georeference it, re-decide the elements against it, and accept, reject or undo a change in the
/// building. Each runs on the ingest's writer thread, between observations, and ends the same way: the commit
/// published, the knowledge base's facts following the committed plan and the plan checks refreshed before the
/// next observation is decided, and the command's live event in the commit's events. See WorldPort for each.
class PlanCommands {
 public:
  explicit PlanCommands(PlanParts parts) : parts_(parts) {}
  PlanCommands(const PlanCommands&) = delete;
  PlanCommands& operator=(const PlanCommands&) = delete;

  std::int64_t load_floor_plan(apriori::FloorPlan plan);
  PlacementOutcome place(world::PlacementChange change, std::string payload_json);
  PlacementOutcome undo_placement(std::string observer);
  /// The search runs on the calling thread against a snapshot and a copy of the grid (the writer goes on
  /// meanwhile), one at a time; only the placement found is applied on the writer.
  AlignOutcome align(AlignRequest request);
  RedecideOutcome redecide(std::string observer);
  std::int64_t set_georeference(std::optional<apriori::Georeference> georeference);

  std::vector<world::Change> changes(std::shared_ptr<const world::WorldState>& state,
                                     std::shared_ptr<const world::PlanReport>& evidence) const;
  ChangeOutcome decide_change(const std::string& change_id, bool accept, std::string observer);
  ChangeOutcome undo_change(std::string observer);

 private:
  template <typename F>
  auto on_writer(F&& work) -> decltype(work()) {
    return parts_.ingest.run_command(std::forward<F>(work));
  }
  std::shared_ptr<const world::WorldState> snapshot() const { return parts_.writer.snapshot(); }
  const world::WorldOptions& world_options() const { return parts_.options.world; }

  /// Which of the knowledge base's facts a committed plan change touched.
  enum class Facts {
    objects,  // the plan's objects moved (a placement): their edge facts
    all,      // objects and elements (a plan edit that may remove or add elements)
  };
  /// After a commit that changed the plan: the facts follow the published map, and the plan checks (evidence and
  /// verdicts) are refreshed over the whole plan.
  void follow_plan(Facts facts);

  /// On the writer: applies and commits a placement (`undo`: pops the stack instead of pushing).
  PlacementOutcome place_on_writer(const world::PlacementChange& change, const std::string& payload, bool undo);
  RedecideOutcome redecide_on_writer(const std::string& observer);
  /// On the writer: commits `p`, a plan edit made against `state` for the change `change_id` (`plan`: the plan to
  /// store when the edit changed it; `push`: the accept or reject to push on the stack of decided changes, nullopt
  /// for an undo, which pops it), publishes it, lists the change again or no more, and tells live clients.
  ChangeOutcome commit_change_edit(PreparedUpdate p, const world::WorldState& state, const std::string& change_id,
                                   const std::string& payload, const std::optional<apriori::FloorPlan>& plan,
                                   const std::optional<storage::Store::PlanChangeRecord>& push);

  PlanParts parts_;
  std::atomic<bool> aligning_{false};  // an align search is running
};

}  // namespace wm::service
