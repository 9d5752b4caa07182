#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/diagnostics.h"
#include "rules/engine.h"
#include "server/service/event_log.h"
#include "server/service/ingest_pipeline.h"
#include "server/service/map_writer.h"
#include "server/service/plan_checks.h"
#include "server/service/prolog_worker.h"
#include "server/service/rules_watcher.h"
#include "server/service/world_port.h"
#include "server/storage/store.h"

namespace wm::service {

/// The parts of one map that its rules act on; all must outlive them.
struct RulesParts {
  storage::Store& store;  // the decision log a dry run asks again
  rules::Engine& engine;
  MapWriter& writer;        // the committed map the verdicts are refreshed on
  PlanChecks& plan_checks;  // the evidence the new rules give their verdicts on
  EventLog& events;
  IngestPipeline& ingest;  // its writer thread runs the reloads
  common::Diagnostics& diagnostics;
};

/// A map's rules: their status, a reload (on request, or when a file of the watched rules directory changes), a
/// read-only query and a dry run of a candidate file. A reload runs on the ingest's writer thread, between
/// observations, and refreshes the plan's verdicts on the same evidence before the next observation is decided;
/// queries and dry runs run on a Prolog thread of their own, never on the writer's. See WorldPort for each.
class RulesCommands {
 public:
  /// `watch_dir`: the rules directory to watch (nullopt: reload only on request).
  RulesCommands(RulesParts parts, const std::optional<std::filesystem::path>& watch_dir);
  ~RulesCommands();
  RulesCommands(const RulesCommands&) = delete;
  RulesCommands& operator=(const RulesCommands&) = delete;

  /// Stops watching the rules directory; call before the ingest stops, since a watched edit reloads on its writer.
  void stop_watching();

  rules::RulesStatus status();
  rules::RulesStatus reload();
  rules::QueryResult query(const std::string& goal, std::size_t max_solutions);
  DryRunOutcome dry_run(const rules::RuleText& candidate, std::size_t count);

 private:
  /// A watched rule file changed: reload, and tell the diagnostics how it went (a rejected edit is no error).
  void on_files_changed();
  /// What the watcher watches: the shared directory, and the map's own rules directory with the ones between.
  std::vector<std::filesystem::path> watched_dirs(const std::filesystem::path& shared) const;

  RulesParts parts_;
  std::unique_ptr<PrologWorker> reader_;  // queries and dry runs
  std::unique_ptr<RulesWatcher> watcher_;
};

}  // namespace wm::service
