#pragma once

#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/diagnostics.h"
#include "rules/engine.h"
#include "server/service/grid_store.h"
#include "server/world/changes.h"
#include "server/world/plan_evidence.h"
#include "server/world/world_state.h"

namespace wm::service {

struct PlanChecksOptions {
  /// How the plan's edges are checked against the grid (the sample step is the grid's cell size).
  world::PlanEvidenceOptions evidence;
  /// Which differences between plan and building are listed as changes.
  world::ChangeOptions changes;
  std::size_t max_verdicts = 100000;  // asked of the rules per check
};

/// The plan against the building: the grid's evidence on every drawn edge (and the beams counted there), handed to
/// the rules as facts, the rules' verdicts on it (missing, partly missing, gone), and the changes a person may accept
/// or reject, less those rejected. The writer refreshes it; anyone reads the last report.
class PlanChecks {
 public:
  /// `rejected`: the change ids rejected before (from the store). `diagnostics` hears of the refreshes that failed.
  PlanChecks(const PlanChecksOptions& options, const GridStore& grid, rules::Engine& engine,
             common::Diagnostics& diagnostics, std::set<std::string> rejected = {});
  PlanChecks(const PlanChecks&) = delete;
  PlanChecks& operator=(const PlanChecks&) = delete;

  /// The evidence and verdicts as last refreshed (never null).
  std::shared_ptr<const world::PlanReport> report() const;
  /// On the writer: checks the edges of `state` in `region` (every edge when nullopt: a new plan or placement, or the
  /// start) against the grid, replaces the rules' evidence facts for them, asks the rules for their verdicts and
  /// publishes the new report; edges outside the region keep theirs. `verdicts_only`: the evidence stands, the rules
  /// changed. Failures are reported to the diagnostics and leave the previous report.
  void refresh(const world::WorldState& state, const std::optional<world::Box>& region, bool verdicts_only = false);
  /// The differences between `state`'s plan and the building, less the rejected ones.
  std::vector<world::Change> changes(const world::WorldState& state, const world::PlanReport* report) const;
  void reject(const std::string& change_id);
  /// An undone rejection: the change is listed again.
  void unreject(const std::string& change_id);

 private:
  const PlanChecksOptions options_;
  const GridStore& grid_;
  rules::Engine& engine_;
  common::Diagnostics& diagnostics_;
  mutable std::mutex report_mutex_;
  std::shared_ptr<const world::PlanReport> report_ = std::make_shared<const world::PlanReport>();
  mutable std::mutex rejected_mutex_;
  std::set<std::string> rejected_;  // change ids a person rejected (not undone)
};

}  // namespace wm::service
