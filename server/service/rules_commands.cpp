#include "server/service/rules_commands.h"

#include <utility>
#include <vector>

#include "server/json/events_json.h"

namespace wm::service {

std::vector<std::filesystem::path> RulesCommands::watched_dirs(const std::filesystem::path& shared) const {
  std::vector<std::filesystem::path> dirs{shared};
  const auto& own = parts_.engine.map_rules_dir();
  if (own.empty()) return dirs;
  // The directories between the shared one and the map's own too: creating them is how its first file comes.
  const auto below = own.lexically_relative(shared);
  if (!below.empty() && *below.begin() != "..") {
    auto dir = shared;
    for (const auto& part : below) {
      dir /= part;
      dirs.push_back(dir);
    }
  } else {
    dirs.push_back(own);
  }
  return dirs;
}

RulesCommands::RulesCommands(RulesParts parts, const std::optional<std::filesystem::path>& watch_dir)
    : parts_(parts), reader_(std::make_unique<PrologWorker>(parts.engine, 64, "knowledge-base query")) {
  if (watch_dir) watcher_ = std::make_unique<RulesWatcher>(watched_dirs(*watch_dir), [this] { on_files_changed(); });
}

RulesCommands::~RulesCommands() {
  stop_watching();
  reader_.reset();
}

void RulesCommands::stop_watching() { watcher_.reset(); }

rules::RulesStatus RulesCommands::status() { return parts_.engine.status(); }

rules::RulesStatus RulesCommands::reload() {
  return parts_.ingest.run_command([this] {
    auto& engine = parts_.engine;
    try {
      auto status = engine.reload();
      parts_.plan_checks.refresh(*parts_.writer.snapshot(), std::nullopt, true);  // new rules, same evidence
      parts_.events.publish(events::EventKind::rules, [&] { return json_codec::rules_event(status); });
      return status;
    } catch (const rules::RuleError&) {
      parts_.events.publish(events::EventKind::rules, [&] { return json_codec::rules_event(engine.status()); });
      throw;
    }
  });
}

void RulesCommands::on_files_changed() {
  auto& diagnostics = parts_.diagnostics;
  try {
    const auto status = reload();
    diagnostics.report(common::Severity::info, "rules",
                       "rules reloaded (generation " + std::to_string(status.generation) + ", " +
                           std::to_string(status.files.size()) + " files)");
  } catch (const rules::RuleError& e) {
    diagnostics.report(common::Severity::warning, "rules",
                       std::string("rules edit rejected, the previous rules stay active:\n") + e.what());
  } catch (const std::exception& e) {
    diagnostics.report(common::Severity::error, "rules", std::string("rules reload failed: ") + e.what());
  }
}

rules::QueryResult RulesCommands::query(const std::string& goal, std::size_t max_solutions) {
  return reader_->run([this, goal, max_solutions] { return parts_.engine.query(goal, max_solutions); });
}

DryRunOutcome RulesCommands::dry_run(const rules::RuleText& candidate, std::size_t count) {
  return reader_->run([this, candidate, count] {
    const auto recorded = parts_.store.latest_decisions(count);
    std::vector<rules::DecisionQuery> queries;
    queries.reserve(recorded.size());
    for (const auto& d : recorded) queries.push_back(d.query());
    const auto answers = parts_.engine.dry_run(candidate, queries);
    DryRunOutcome outcome;
    outcome.redecided = recorded.size();
    for (std::size_t i = 0; i < recorded.size(); ++i) {
      const auto& before = recorded[i];
      const auto& after = answers[i];
      if (before.rule != after.rule || rules::wire_name(before.action) != after.action)
        outcome.changes.push_back({before, after});
    }
    return outcome;
  });
}

}  // namespace wm::service
