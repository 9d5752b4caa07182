#pragma once

// Fakes of the service's ports for handler tests: one class per port, each the size of its port, sharing one
// FakeLedger (the world state the test sets, the calls received, an exception to throw from the next call), and
// FakeWorldPort, all six at once, for tests that go through the whole router. No thread, no store, no Prolog.
#include <algorithm>
#include <chrono>
#include <exception>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "fusion/grid/occupancy_grid.h"
#include "server/service/world_port.h"

namespace wm::testing {

/// What the fakes share: the world state, the calls in order, and the failure to throw next.
class FakeLedger {
 public:
  FakeLedger() : state_(std::make_shared<world::WorldState>()) {}
  FakeLedger(const FakeLedger&) = delete;  // shared by the fakes of one service: never copied or moved
  FakeLedger& operator=(const FakeLedger&) = delete;

  /// Replaces the world with `plan` loaded as drawn (version 1).
  void load_plan(const apriori::FloorPlan& plan) {
    auto update = world::apply_floor_plan(world::WorldState{}, plan, options_);
    state_ = std::make_shared<world::WorldState>(std::move(update.state));
  }
  world::WorldState& state() { return *state_; }
  /// The next call of any port method throws this (then it is cleared).
  void fail_next(std::exception_ptr failure) { failure_ = std::move(failure); }
  std::vector<std::string> calls;  // method names, in order
  std::string last_payload;        // the body journaled by the last post or placement

  static world::DecisionRecord decision(rules::Action action, const std::string& element) {
    world::DecisionRecord d;
    d.seq = 1;
    d.action = action;
    d.rule = "test_rule";
    d.element = element;
    return d;
  }

 protected:
  void enter(const std::string& name) {
    calls.push_back(name);
    if (failure_) std::rethrow_exception(std::exchange(failure_, nullptr));
  }

  world::WorldOptions options_;
  std::shared_ptr<world::WorldState> state_;

 private:
  std::exception_ptr failure_;
};

/// The map: the ledger's state, a decision log the test fills, the plan report it sets.
class FakeMap : public virtual service::MapPort, public virtual FakeLedger {
 public:
  std::vector<world::DecisionRecord> logged;  // what decisions() and object_decisions() answer
  std::optional<std::string> last_element_filter;
  std::shared_ptr<world::PlanReport> plan_report_answer = std::make_shared<world::PlanReport>();

  std::shared_ptr<const world::WorldState> snapshot() const override { return state_; }
  const world::WorldOptions& world_options() const override { return options_; }
  std::vector<world::DecisionRecord> decisions(std::int64_t since_seq, std::size_t limit,
                                               const std::optional<std::string>& element) override {
    enter("decisions");
    last_element_filter = element;
    std::vector<world::DecisionRecord> rows;
    for (const auto& d : logged)
      if (d.seq > since_seq && rows.size() < limit && (!element || d.element == element)) rows.push_back(d);
    return rows;
  }
  std::vector<world::DecisionRecord> object_decisions(const std::string& object_id, std::size_t) override {
    enter("object_decisions");
    std::vector<world::DecisionRecord> rows;
    for (const auto& d : logged)
      if (d.object == object_id) rows.push_back(d);
    return rows;
  }
  std::optional<service::MapRemovals> removed_since(std::int64_t since, std::int64_t) const override {
    if (since < 0) return std::nullopt;
    return service::MapRemovals{};
  }

  std::shared_ptr<const world::PlanReport> plan_report() const override { return plan_report_answer; }
};

/// The grid: an empty grid of 0.05 m cells unless the test sets one.
class FakeGrid : public virtual service::GridPort, public virtual FakeLedger {
 public:
  std::optional<fusion::OccupancyGrid> grid;

  double grid_resolution_m() const override { return the_grid().resolution_m(); }
  std::optional<fusion::GridGeometry> grid_bounds() const override { return the_grid().bounds(); }
  service::GridLayerValues grid_layer(fusion::GridLayer layer, const fusion::GridGeometry& region) const override {
    return {the_grid().export_layer(fusion::stored_layer(layer).value(), region), 4};
  }
  service::GridSonarStatus grid_sonar() const override { return {}; }
  service::GridTiles grid_tiles() const override {
    service::GridTiles result{the_grid().tile_size_cells(), the_grid().resolution_m(), 4, {}};
    for (const auto& [index, revision] : the_grid().tile_revisions())
      result.tiles.push_back({index.x, index.y, revision});
    return result;
  }
  std::optional<service::GridTileValues> grid_tile(fusion::GridLayer layer, std::int64_t tx,
                                                   std::int64_t ty) const override {
    const auto revision = the_grid().tile_revision({tx, ty});
    if (revision == 0) return std::nullopt;
    return service::GridTileValues{
        the_grid().export_layer(fusion::stored_layer(layer).value(), the_grid().tiles_geometry({tx, ty}, {tx, ty})),
        revision};
  }
  std::optional<service::GridTileValues> grid_tile_layers(std::int64_t tx, std::int64_t ty) const override {
    const auto revision = the_grid().tile_revision({tx, ty});
    if (revision == 0) return std::nullopt;
    return service::GridTileValues{the_grid().export_tile_layers({tx, ty}), revision};
  }

 protected:
  const fusion::OccupancyGrid& the_grid() const { return grid ? *grid : empty_grid_; }

 private:
  fusion::OccupancyGrid empty_grid_{fusion::GridOptions{}};
};

/// Posts answered with canned decisions; what was posted is kept.
class FakeIngest : public virtual service::IngestPort, public virtual FakeLedger {
 public:
  bool replay = false;          // posts answer as replays
  bool grid_has_lines = false;  // extract_grid_lines finds a line
  std::optional<world::Observation> last_observation;
  std::optional<world::ScanObservation> last_scan;
  std::optional<std::string> last_request_id;

  service::PrimitivesOutcome post_primitives(world::Observation observation, std::string payload_json,
                                             std::optional<std::string> request_id) override {
    enter("post_primitives");
    last_observation = std::move(observation);
    last_payload = std::move(payload_json);
    last_request_id = std::move(request_id);
    return {7, 3, {decision(rules::Action::add, "e1")}, replay};
  }
  service::ScanOutcome post_scan(world::ScanObservation scan, std::string payload_json,
                                 std::optional<std::string> request_id) override {
    enter("post_scan");
    last_scan = std::move(scan);
    last_payload = std::move(payload_json);
    last_request_id = std::move(request_id);
    // Placed 2 cm east and 0.01 rad turned from where it was posted.
    return {4, 4, service::PrimitivesOutcome{8, 5, {decision(rules::Action::merge, "e2")}, replay}, replay,
            service::ScanPlacement{{1.0, 2.0, 0.5}, {1.02, 2.0, 0.51}}};
  }
  std::vector<world::ScanObservation> last_batch;
  // Scan i of a batch is journaled as seq 10 + i.
  std::vector<service::ScanOutcome> post_scans(std::vector<world::ScanObservation> scans, std::string_view body,
                                               std::optional<std::string> request_id) override {
    enter("post_scans");
    last_batch = std::move(scans);
    last_payload = std::string(body);
    last_request_id = std::move(request_id);
    std::vector<service::ScanOutcome> outcomes;
    for (std::size_t i = 0; i < last_batch.size(); ++i) {
      const auto seq = static_cast<std::int64_t>(10 + i);
      outcomes.push_back({seq, seq, std::nullopt, replay, std::nullopt});
    }
    return outcomes;
  }
  std::optional<service::PrimitivesOutcome> extract_grid_lines() override {
    enter("extract_grid_lines");
    if (!grid_has_lines) return std::nullopt;
    return service::PrimitivesOutcome{11, 6, {decision(rules::Action::add, "e3")}, false};
  }
  pipeline::NetworkStats network_stats() const override {
    pipeline::NetworkStats stats;
    stats.source = "fake.yaml";
    stats.ports.push_back({"matcher", "laser", "scan", pipeline::PortPolicy::fifo, 256, 3, 7, 100, 0, 2});
    stats.functions.push_back({"matcher", "laser", {"laser"}, {}, 0, 97, 0, 0.5, 0.01});
    stats.executors.push_back({"world", {"matcher"}, 120, 0.5, 2.0});
    stats.connections.push_back("matcher.decided -> store.in");
    return stats;
  }
};

/// The plan's writes: loads, placements, changes accepted and rejected.
class FakePlan : public virtual service::PlanPort, public virtual FakeLedger {
 public:
  std::optional<apriori::FloorPlan> last_plan;
  std::optional<world::PlacementChange> last_placement;
  std::optional<service::AlignRequest> last_align;
  service::AlignOutcome align_answer;
  std::optional<std::pair<std::string, bool>> last_change;  // (id, accept) of the last decide_change
  std::string last_decider;
  /// The changes decide_change may take (FakeWorldPort lists the map's).
  std::function<std::vector<world::Change>()> listed_changes = [] { return std::vector<world::Change>{}; };

  std::int64_t load_floor_plan(apriori::FloorPlan plan) override {
    enter("load_floor_plan");
    last_plan = std::move(plan);
    return 9;
  }
  service::PlacementOutcome place_floor_plan(world::PlacementChange change, std::string payload_json) override {
    enter("place_floor_plan");
    last_payload = std::move(payload_json);
    last_placement = change;
    auto update = world::apply_placement(*state_, change, state_->last_observation_seq + 1);
    state_ = std::make_shared<world::WorldState>(update.state);
    return {state_->version, update.decisions.at(0)};
  }
  service::AlignOutcome align_floor_plan(service::AlignRequest request) override {
    enter("align_floor_plan");
    last_align = request;
    return align_answer;
  }
  service::PlacementOutcome undo_placement(std::string) override {
    enter("undo_placement");
    return {1, decision(rules::Action::place, "")};
  }
  service::RedecideOutcome redecide_elements(std::string) override {
    enter("redecide_elements");
    return {2, 3, {decision(rules::Action::confirm, "e1")}};
  }
  std::int64_t set_georeference(std::optional<apriori::Georeference> georeference) override {
    enter("set_georeference");
    state_->georeference = georeference;
    return ++state_->version;
  }
  service::ChangeOutcome decide_change(const std::string& change_id, bool accept, std::string observer) override {
    enter("decide_change");
    const auto listed = listed_changes();
    if (std::none_of(listed.begin(), listed.end(), [&](const world::Change& c) { return c.id == change_id; }))
      throw service::NotFound("no change '" + change_id + "' is listed now");
    last_change = {change_id, accept};
    last_decider = observer;
    return {state_->version + 1, decision(accept ? rules::Action::accept : rules::Action::reject, ""), change_id, {}};
  }
  service::ChangeOutcome undo_change(std::string observer) override {
    enter("undo_change");
    last_decider = observer;
    return {state_->version + 1, decision(rules::Action::undo, ""), "c000000000000", {}};
  }
};

/// The knowledge base's answers, set by the test.
class FakeRules : public virtual service::RulesPort, public virtual FakeLedger {
 public:
  rules::QueryResult query_answer;
  service::DryRunOutcome dry_run_answer;
  std::string last_goal;
  std::optional<rules::RuleText> last_candidate;

  rules::RulesStatus rules_status() override {
    enter("rules_status");
    return {{{"/srv/wm/prolog/world_model.pl", "abc", 1}}, "", 1};
  }
  rules::RulesStatus reload_rules() override {
    enter("reload_rules");
    return {{{"/srv/wm/prolog/world_model.pl", "def", 2}}, "", 2};
  }
  rules::QueryResult query(const std::string& goal, std::size_t) override {
    enter("query");
    last_goal = goal;
    return query_answer;
  }
  service::DryRunOutcome dry_run(const rules::RuleText& candidate, std::size_t) override {
    enter("dry_run");
    last_candidate = candidate;
    return dry_run_answer;
  }
};

/// The robots: a real registry.
class FakeRobots : public virtual service::RobotPort, public virtual FakeLedger {
 public:
  service::RobotRegistry registry;  // what the robots routes read and write

  std::vector<service::RobotState> robots() const override { return registry.list(); }
  std::optional<service::RobotState> robot(const std::string& id) const override { return registry.find(id); }
  service::RobotState put_robot_pose(const std::string& id, service::RobotPose pose, bool stopped) override {
    enter("put_robot_pose");
    pose.received_at_unix_s =  // as the service does: the server's clock
        std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    registry.on_pose(id, std::move(pose), stopped);
    return *registry.find(id);
  }
  const service::RobotOptions& robot_options() const override { return registry.options(); }
};

/// All six ports at once, as the router sees the service.
class FakeWorldPort : public service::WorldPort,
                      public FakeMap,
                      public FakeGrid,
                      public FakeIngest,
                      public FakePlan,
                      public FakeRules,
                      public FakeRobots {
 public:
  FakeWorldPort() {
    listed_changes = [this] {
      std::shared_ptr<const world::WorldState> state;
      std::shared_ptr<const world::PlanReport> evidence;
      return changes(state, evidence);
    };
  }
  std::optional<service::PrimitivesOutcome> extract_grid_lines() override {
    grid_has_lines = grid.has_value();
    return FakeIngest::extract_grid_lines();
  }
};

}  // namespace wm::testing
