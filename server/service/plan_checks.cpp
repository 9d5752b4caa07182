#include "server/service/plan_checks.h"

#include <algorithm>
#include <tuple>

namespace wm::service {
namespace {

/// "<object>/<k>" back to k, when the id is that object's.
std::optional<std::size_t> edge_index(const std::string& object_id, const std::string& edge_id) {
  if (edge_id.size() <= object_id.size() + 1 || edge_id.compare(0, object_id.size(), object_id) != 0 ||
      edge_id[object_id.size()] != '/')
    return std::nullopt;
  std::size_t k = 0;
  for (std::size_t i = object_id.size() + 1; i < edge_id.size(); ++i) {
    if (edge_id[i] < '0' || edge_id[i] > '9' || k > (std::size_t{1} << 40)) return std::nullopt;
    k = k * 10 + static_cast<std::size_t>(edge_id[i] - '0');
  }
  return k;
}

}  // namespace

PlanChecks::PlanChecks(const PlanChecksOptions& options, const GridStore& grid, rules::Engine& engine,
                       common::Diagnostics& diagnostics, std::set<std::string> rejected)
    : options_(options), grid_(grid), engine_(engine), diagnostics_(diagnostics), rejected_(std::move(rejected)) {}

std::shared_ptr<const world::PlanReport> PlanChecks::report() const {
  std::lock_guard lock(report_mutex_);
  return report_;
}

void PlanChecks::refresh(const world::WorldState& state, const std::optional<world::Box>& region, bool verdicts_only) {
  try {
    const auto previous = report();
    auto report = std::make_shared<world::PlanReport>();
    report->map_version = state.version;
    std::vector<world::EdgeEvidence> fresh;
    report->grid_revision = previous->grid_revision;
    if (!verdicts_only) fresh = grid_.edge_evidence(state, region, options_.evidence, report->grid_revision);
    std::vector<rules::EdgeEvidenceFacts> facts;
    std::vector<rules::EdgeKey> keys;
    std::set<std::pair<std::size_t, std::size_t>> refreshed;
    std::set<std::string> objects_refreshed;
    facts.reserve(fresh.size());
    for (const auto& e : fresh) {
      const auto& object_id = state.objects[e.object].plan->id;
      rules::EdgeEvidenceFacts f{
          object_id,    world::edge_id(object_id, e.edge), e.backed, e.seen_through, e.observed, {}, e.beams_through,
          e.beams_ended};
      for (const auto& stretch : e.seen_through_stretches)
        f.stretches.push_back({stretch.s0_m, stretch.s1_m, stretch.beams_through, stretch.beams_ended});
      keys.push_back({f.object_id, f.edge_id});
      facts.push_back(std::move(f));
      refreshed.insert({e.object, e.edge});
      objects_refreshed.insert(object_id);
    }
    // A region's check leaves the evidence of the edges outside it as it was; a whole check replaces it all (the
    // plan or its placement changed, or the server started).
    const bool whole = !region && !verdicts_only;
    if (!verdicts_only) engine_.set_edge_evidence(facts, whole);
    const bool scoped = region.has_value() && !verdicts_only;
    const auto verdicts = engine_.plan_verdicts(scoped ? std::optional(keys) : std::nullopt, options_.max_verdicts);

    report->edges = verdicts_only ? previous->edges : std::move(fresh);
    if (scoped)
      for (const auto& e : previous->edges)
        if (!refreshed.contains({e.object, e.edge}) && e.object < state.objects.size()) report->edges.push_back(e);
    std::sort(report->edges.begin(), report->edges.end(), [](const auto& a, const auto& b) {
      return std::pair{a.object, a.edge} < std::pair{b.object, b.edge};
    });
    if (scoped)
      for (const auto& v : previous->verdicts) {
        const auto index = state.objects.index_of(v.object_id);
        if (!index) continue;  // the plan changed since
        const bool asked = v.edge ? refreshed.contains({*index, *v.edge}) : objects_refreshed.contains(v.object_id);
        if (!asked) report->verdicts.push_back(v);
      }
    for (const auto& f : verdicts) {
      world::Verdict v;
      v.object_id = f.object_id;
      if (f.edge_id) {
        v.edge = edge_index(f.object_id, *f.edge_id);
        if (!v.edge) continue;  // not an edge of this plan: nothing to show it on
      }
      v.verdict = f.verdict;
      v.stretch = {f.s0_m, f.s1_m};
      v.rule = f.rule;
      v.explanation = f.explanation;
      report->verdicts.push_back(std::move(v));
    }
    std::sort(report->verdicts.begin(), report->verdicts.end(), [&state](const auto& a, const auto& b) {
      const auto ia = state.objects.index_of(a.object_id).value_or(0),
                 ib = state.objects.index_of(b.object_id).value_or(0);
      const auto ea = a.edge ? static_cast<std::int64_t>(*a.edge) : -1,
                 eb = b.edge ? static_cast<std::int64_t>(*b.edge) : -1;
      return std::tuple{ia, ea, a.stretch.s0_m} < std::tuple{ib, eb, b.stretch.s0_m};
    });
    std::lock_guard lock(report_mutex_);
    report_ = std::move(report);
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::warning, "plan_checks",
                        std::string("the plan's evidence was not refreshed: ") + e.what());
  }
}

std::vector<world::Change> PlanChecks::changes(const world::WorldState& state, const world::PlanReport* report) const {
  auto list = world::list_changes(state, report, options_.changes);
  std::lock_guard lock(rejected_mutex_);
  std::erase_if(list, [this](const world::Change& c) { return rejected_.contains(c.id); });
  return list;
}

void PlanChecks::reject(const std::string& change_id) {
  std::lock_guard lock(rejected_mutex_);
  rejected_.insert(change_id);
}

void PlanChecks::unreject(const std::string& change_id) {
  std::lock_guard lock(rejected_mutex_);
  rejected_.erase(change_id);
}

}  // namespace wm::service
