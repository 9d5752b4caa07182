#include "server/service/world_service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <system_error>
#include <tuple>
#include <type_traits>
#include <variant>

#include "server/service/knowledge_facts.h"
#include "server/service/map_recovery.h"

namespace wm::service {
namespace {

std::set<std::string> rejected_changes(storage::Store& store) {
  std::set<std::string> ids;
  for (const auto& decided : store.plan_changes())
    if (decided.verdict == "rejected") ids.insert(decided.change_id);
  return ids;
}

}  // namespace

WorldService::WorldService(const ServiceOptions& options, storage::Store& store, rules::Engine& engine,
                           common::Diagnostics& diagnostics, events::EventHub* events)
    : options_(options),
      store_(store),
      engine_(engine),
      diagnostics_(diagnostics),
      event_log_(events, diagnostics),
      writer_(options.map, store.load(options.map.world), engine, diagnostics),
      grid_(options.grids, store, diagnostics),
      plan_checks_(options.plan_checks, grid_, engine, diagnostics, rejected_changes(store)) {
  // One read of the robots' journal serves both: whether sonar was seen, and the robots themselves.
  auto journals = store_.robot_journal(robots_.options().track_points);
  replay_journal_into_grid(store_, grid_, *snapshot(), journal_has_sonar(journals));
  restore_robots(std::move(journals), robots_);
  ingest_ = std::make_unique<IngestPipeline>(
      options_.ingest, IngestParts{store_, engine_, writer_, grid_, plan_checks_, robots_, event_log_, diagnostics_});
  plan_ = std::make_unique<PlanCommands>(
      PlanParts{options_.map, store_, engine_, writer_, grid_, plan_checks_, event_log_, *ingest_});
  // The knowledge base mirrors the committed map; fill it before the first request is taken.
  run_command([this] {
    const auto& map_options = options_.map;
    sync_all_facts(engine_, *snapshot(), map_options.world);
    std::vector<rules::DecisionFacts> recent;
    for (const auto& d : store_.latest_decisions(map_options.decision_facts_kept))
      recent.push_back(decision_facts(d, 0));
    engine_.add_decisions(recent, map_options.decision_facts_kept);
    // The evidence comes from the grid as the journal rebuilt it, so a restart sees what an uninterrupted run saw.
    plan_checks_.refresh(*snapshot(), std::nullopt);
    ingest_->trim_left_undone();
    return 0;
  });
  rules_ = std::make_unique<RulesCommands>(
      RulesParts{store_, engine_, writer_, plan_checks_, event_log_, *ingest_, diagnostics_}, options_.watch_rules_dir);
}

WorldService::~WorldService() {
  if (rules_) rules_->stop_watching();  // a watched edit reloads on the ingest's writer
  ingest_->stop();                      // its queued commands still reach ingest_
  ingest_.reset();
  try {
    grid_.flush(true);  // not past a gap: the journal replays from there at start
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::warning, "grid",
                        std::string("final grid flush failed (the journal still has every scan): ") + e.what());
  }
  rules_.reset();
}

ScanOutcome WorldService::post_scan(world::ScanObservation scan, std::string payload_json,
                                    std::optional<std::string> request_id) {
  return ingest_->post_scan(std::move(scan), std::move(payload_json), std::move(request_id));
}

std::vector<ScanOutcome> WorldService::post_scans(std::vector<world::ScanObservation> scans, std::string_view body,
                                                  std::optional<std::string> request_id) {
  return ingest_->post_scans(std::move(scans), body, std::move(request_id));
}

PrimitivesOutcome WorldService::post_primitives(world::Observation observation, std::string payload_json,
                                                std::optional<std::string> request_id) {
  return ingest_->post_primitives(std::move(observation), std::move(payload_json), std::move(request_id));
}

bool WorldService::accepts_scans(const std::string& sensor) const { return ingest_->accepts_scans(sensor); }

pipeline::NetworkStats WorldService::network_stats() const { return ingest_->stats(); }

pipeline::NetworkStats WorldService::set_network_subtask(const std::string& name, bool running) {
  ingest_->set_subtask(name, running);
  return ingest_->stats();
}

pipeline::NetworkStats WorldService::set_network_params(const std::string& component,
                                                        const std::map<std::string, std::string>& changes) {
  ingest_->set_params(component, changes);
  return ingest_->stats();
}

std::shared_ptr<const world::PlanReport> WorldService::plan_report() const { return plan_checks_.report(); }

std::shared_ptr<const world::PlanReport> WorldService::refresh_plan_report() {
  run_command([this] {
    plan_checks_.refresh(*snapshot(), std::nullopt);
    return 0;
  });
  return plan_report();
}

std::optional<PrimitivesOutcome> WorldService::extract_grid_lines() {
  return run_command([this] { return ingest_->extract_grid_lines(); });
}

std::shared_ptr<const world::WorldState> WorldService::snapshot() const { return writer_.snapshot(); }

std::optional<MapRemovals> WorldService::removed_since(std::int64_t since, std::int64_t up_to) const {
  return writer_.published().removed_since(since, up_to);
}

std::int64_t WorldService::load_floor_plan(apriori::FloorPlan plan) { return plan_->load_floor_plan(std::move(plan)); }

PlacementOutcome WorldService::place_floor_plan(world::PlacementChange change, std::string payload_json) {
  return plan_->place(std::move(change), std::move(payload_json));
}

AlignOutcome WorldService::align_floor_plan(AlignRequest request) { return plan_->align(std::move(request)); }

PlacementOutcome WorldService::undo_placement(std::string observer) {
  return plan_->undo_placement(std::move(observer));
}

RedecideOutcome WorldService::redecide_elements(std::string observer) { return plan_->redecide(std::move(observer)); }

std::int64_t WorldService::set_georeference(std::optional<apriori::Georeference> georeference) {
  return plan_->set_georeference(std::move(georeference));
}

std::vector<world::Change> WorldService::changes(std::shared_ptr<const world::WorldState>& state,
                                                 std::shared_ptr<const world::PlanReport>& evidence) const {
  return plan_->changes(state, evidence);
}

ChangeOutcome WorldService::decide_change(const std::string& change_id, bool accept, std::string observer) {
  return plan_->decide_change(change_id, accept, std::move(observer));
}

ChangeOutcome WorldService::undo_change(std::string observer) { return plan_->undo_change(std::move(observer)); }

rules::RulesStatus WorldService::rules_status() { return rules_->status(); }

rules::RulesStatus WorldService::reload_rules() { return rules_->reload(); }

rules::QueryResult WorldService::query(const std::string& goal, std::size_t max_solutions) {
  return rules_->query(goal, max_solutions);
}

DryRunOutcome WorldService::dry_run(const rules::RuleText& candidate, std::size_t count) {
  return rules_->dry_run(candidate, count);
}

std::vector<world::DecisionRecord> WorldService::decisions(std::int64_t since_seq, std::size_t limit,
                                                           const std::optional<std::string>& element) {
  return store_.decisions(since_seq, limit, element);
}

std::vector<world::DecisionRecord> WorldService::object_decisions(const std::string& object_id, std::size_t limit) {
  return store_.object_decisions(object_id, limit);
}

double WorldService::grid_resolution_m() const { return grid_.resolution_m(); }

std::optional<fusion::GridGeometry> WorldService::grid_bounds() const { return grid_.bounds(); }

GridLayerValues WorldService::grid_layer(fusion::GridLayer layer, const fusion::GridGeometry& region) const {
  return grid_.layer(layer, region);
}

GridSonarStatus WorldService::grid_sonar() const { return grid_.sonar(); }

GridTiles WorldService::grid_tiles() const { return grid_.tiles(); }

std::optional<GridTileValues> WorldService::grid_tile(fusion::GridLayer layer, std::int64_t tx, std::int64_t ty) const {
  return grid_.tile(layer, tx, ty);
}

std::optional<GridTileValues> WorldService::grid_tile_layers(std::int64_t tx, std::int64_t ty) const {
  return grid_.tile_layers(tx, ty);
}

RobotState WorldService::put_robot_pose(const std::string& id, RobotPose pose, bool stopped) {
  pose.received_at_unix_s = now_unix_s();
  store_.commit_robot_pose({id, pose.x, pose.y, pose.theta, pose.cov, pose.stamp_s, pose.received_at_unix_s,
                            stopped ? "stopped" : "moving"});
  auto live = event_log_.begin();  // not a map commit: its place is when it is heard
  add_robot_event(live, robots_, robots_.on_pose(id, pose, stopped));
  return *robots_.find(id);
}

}  // namespace wm::service
