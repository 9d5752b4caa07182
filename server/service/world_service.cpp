#include "server/service/world_service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <system_error>
#include <tuple>
#include <type_traits>
#include <variant>

#include "fusion/grid/scan_geometry.h"
#include "fusion/grid/sensor_model.h"
#include "server/json/events_json.h"
#include "server/service/knowledge_facts.h"
#include "server/world/plan_edit.h"
#include "server/world/scan_alignment.h"

namespace wm::service {
namespace {

std::set<std::string> rejected_changes(storage::Store& store) {
  std::set<std::string> ids;
  for (const auto& decided : store.plan_changes())
    if (decided.verdict == "rejected") ids.insert(decided.change_id);
  return ids;
}

}  // namespace

namespace {

// A journaled scan; rows stored before the journal kept scans in binary form hold the request body instead.
// @throw json_codec::CodecError for such a body this build does not read.
world::ScanObservation scan_of(storage::JournaledScan&& record) {
  if (record.scan) return std::move(*record.scan);
  return json_codec::parse_scan(record.legacy_json, json_codec::ScanLimits{});
}

// Calls `visit(seq, scan record)` for every journaled scan past `after`, in order, reading a page at a time.
template <typename Visit>
void for_each_scan_after(storage::Store& store, std::int64_t after, Visit visit) {
  constexpr std::size_t kPage = 256;
  for (;;) {
    auto page = store.scans_after(after, kPage);
    for (auto& record : page) {
      after = record.seq;
      visit(record.seq, std::move(record));
    }
    if (page.size() < kPage) return;
  }
}

}  // namespace

double now_unix_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

WorldService::WorldService(const ServiceOptions& options, storage::Store& store, rules::Engine& engine,
                           common::Diagnostics& diagnostics, events::EventHub* events)
    : options_(options),
      store_(store),
      engine_(engine),
      diagnostics_(diagnostics),
      event_log_(events, diagnostics),
      published_(store.load(options.world)),
      grid_(GridStoreOptions{options.grid, options.grid_flush_interval, options.beam_crossings}, store, diagnostics),
      plan_checks_(PlanChecksOptions{options.plan_evidence, options.changes}, grid_, engine, diagnostics,
                   rejected_changes(store)) {
  head_ = published_.current();
  // The journal is the grid's source of truth: a scan is journaled (with its line decisions) before it
  // touches the grid, and the tiles are flushed later. Replaying past the flush brings the grid, and its
  // revision, to the last journaled scan.
  for_each_scan_after(store_, grid_.flushed_scan_seq(), [this](std::int64_t seq, storage::JournaledScan&& record) {
    grid_.insert(scan_of(std::move(record)), seq, *snapshot());
  });
  const std::int64_t last_scan_seq = grid_.last_scan_seq();
  if (last_scan_seq != store_.last_scan_seq())
    throw storage::StorageError("the scan journal ends at " + std::to_string(store_.last_scan_seq()) +
                                " but the grid was rebuilt to " + std::to_string(last_scan_seq));
  // Replayed tiles stay dirty: the next flush (or the one at shutdown) writes them.
  next_scan_seq_ = committed_scan_seq_ = last_scan_seq;
  // The grid trim looks at what the scans since the last one could see: rebuilt from the journal, so a restart trims
  // as an uninterrupted run would. A crash between a scan and the trim it made due leaves that trim undone: it is
  // made now, against the same map and grid the run had then (the journal ends at that scan).
  std::optional<std::pair<std::int64_t, world::Box>> due_trim;
  if (options_.grid_trim_every > 0 && last_scan_seq > 0) {
    const auto every = static_cast<std::int64_t>(options_.grid_trim_every);
    auto since = last_scan_seq - last_scan_seq % every;
    const bool due = last_scan_seq % every == 0 && !store_.has_observation(kTrimObserver, trim_payload(last_scan_seq));
    if (due) since = last_scan_seq - every;
    for_each_scan_after(store_, since, [this](std::int64_t seq, storage::JournaledScan&& record) {
      try {
        add_to_trim_region(scan_of(std::move(record)));
      } catch (const std::exception& e) {
        diagnostics_.report(common::Severity::warning, "grid_trim",
                            "scan " + std::to_string(seq) + " left out of the grid trim: " + e.what());
      }
    });
    if (due && trim_region_) {
      due_trim.emplace(last_scan_seq, *trim_region_);
      trim_region_.reset();
    }
  }
  restore_robots();
  reader_ = std::make_unique<PrologWorker>(engine_, 64, "knowledge-base query");
  const auto spec = options_.network_file ? pipeline::read_task_file(options_.network_file->string())
                                          : pipeline::parse_task(default_network_yaml(), "<default network>");
  // A function that throws is a bug: counted in the network's stats, and reported here with what it said.
  network_ = std::make_unique<pipeline::Network>(
      spec, network_registry(), [this](std::string_view component, std::string_view function, std::string_view what) {
        diagnostics_.report(common::Severity::error, "network",
                            std::string(component) + "." + std::string(function) + " failed: " + std::string(what));
      });
  network_->start();
  // The knowledge base mirrors the committed map; fill it before the first request is taken.
  run_command([this, &due_trim] {
    sync_all_facts(engine_, *snapshot(), options_.world);
    std::vector<rules::DecisionFacts> recent;
    for (const auto& d : store_.latest_decisions(options_.decision_facts_kept)) recent.push_back(decision_facts(d, 0));
    engine_.add_decisions(recent, options_.decision_facts_kept);
    // The evidence comes from the grid as the journal rebuilt it, so a restart sees what an uninterrupted run saw.
    plan_checks_.refresh(*snapshot(), std::nullopt);
    if (due_trim) trim_now(due_trim->first, due_trim->second);
    return 0;
  });
  if (options_.watch_rules_dir) {
    watcher_ = std::make_unique<RulesWatcher>(*options_.watch_rules_dir, [this] { on_rules_changed(); });
  }
}

WorldService::~WorldService() {
  watcher_.reset();
  const auto report = network_->stop(true);
  for (const auto& [port, count] : report.dropped)
    diagnostics_.report(
        common::Severity::warning, "network",
        "stopped with " + std::to_string(count) + " values left in " + port + " (their requests got 503)");
  try {
    grid_.flush(true);  // not past a gap: the journal replays from there at start
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::warning, "grid",
                        std::string("final grid flush failed (the journal still has every scan): ") + e.what());
  }
  reader_.reset();
}

std::optional<storage::RequestRecord> WorldService::known_request(const std::string& request_id, std::string_view kind,
                                                                  std::int64_t hash) {
  auto record = store_.find_request(request_id);
  if (!record) return std::nullopt;
  if (record->kind != kind)
    throw RequestIdConflict("request id '" + request_id + "' was used for a " + record->kind + " request");
  if (record->body_hash != hash)
    throw RequestIdConflict("request id '" + request_id + "' was used with another body (" + record->kind + " " +
                            std::to_string(record->seq) + ")");
  return record;
}

std::optional<ScanOutcome> WorldService::replayed_scan(const std::optional<std::string>& request_id, std::int64_t hash,
                                                       const world::ScanObservation& retried) {
  if (!request_id) return std::nullopt;
  const auto known = known_request(*request_id, "scan", hash);
  if (!known) return std::nullopt;
  ScanOutcome outcome{known->seq, known->grid_revision, std::nullopt, true, std::nullopt};
  if (known->lines_seq)
    outcome.lines =
        PrimitivesOutcome{*known->lines_seq, known->version, store_.observation_decisions(*known->lines_seq), true};
  // The retry posts the same bytes, so the same pose; the journal holds where the first one was placed.
  const auto* posted = std::get_if<fusion::LaserScan>(&retried.scan);
  if (options_.extract_scan_lines && posted) {
    if (const auto journaled = store_.scan(known->seq); journaled && journaled->scan)
      if (const auto* placed = std::get_if<fusion::LaserScan>(&journaled->scan->scan))
        outcome.placement = ScanPlacement{posted->sensor_pose, placed->sensor_pose};
  }
  return outcome;
}

std::optional<WorldService::PreparedUpdate> WorldService::prepare_scan_lines(world::ScanObservation& scan,
                                                                             std::optional<ScanPlacement>& placement) {
  auto* laser = std::get_if<fusion::LaserScan>(&scan.scan);
  if (!options_.extract_scan_lines || !laser) return std::nullopt;
  std::vector<fusion::RangeReading> readings;
  for (std::size_t i = 0; i < laser->ranges_m.size(); ++i) {
    const double r = laser->ranges_m[i];
    // No return (>= range_max) and invalid readings carry no surface.
    if (std::isfinite(r) && r >= laser->range_min_m && r < laser->range_max_m && r > 0)
      readings.push_back({r, fusion::beam_bearing_rad(*laser, i)});
  }
  placement = ScanPlacement{laser->sensor_pose, laser->sensor_pose};
  auto line_options = options_.scan_lines;
  line_options.sigma_range_m = laser->sigma_range_m;
  line_options.sigma_range_relative = laser->sigma_range_per_m;
  // In the sensor's own frame first (the sensor's noise only), so that they can place the sensor.
  const auto local = fusion::extract_scan_lines(readings, fusion::Pose2D{}, Eigen::Matrix3d::Zero(), line_options);
  if (local.empty()) return std::nullopt;
  if (options_.align_scans) {
    const auto alignment =
        world::align_to_map(*head_, local, laser->sensor_pose, scan.pose_cov, options_.world, options_.scan_alignment);
    if (alignment.aligned) {
      placement->placed = alignment.pose;
      laser->sensor_pose = alignment.pose;
    }
  }
  world::Observation observation;
  observation.observer = scan.observer;
  observation.origin = "scan";
  observation.sensor = "laser";
  observation.stamp_s = scan.stamp_s;
  // Which face of each wall the laser saw: the two faces of a thin wall are kept apart by it.
  const Eigen::Vector2d viewpoint(laser->sensor_pose.x_m, laser->sensor_pose.y_m);
  for (const auto& segment : local) {
    const auto placed = fusion::transform_segment(segment, laser->sensor_pose, scan.pose_cov);
    observation.segments.push_back({placed, world::facing_toward(placed, viewpoint)});
  }
  return prepare_update(std::move(observation));
}

void WorldService::add_scan_event(EventLog::Commit& live, const world::ScanObservation& scan, std::int64_t seq) {
  live.add(events::EventKind::scan, [&] {
    constexpr std::size_t kMaxEventPoints = 360;
    const auto changed = grid_.changed_region(scan, 2 * grid_.resolution_m());
    const auto [pose, points] = std::visit(
        [&](const auto& s) {
          return std::pair{s.sensor_pose, fusion::scan_returns(s, kMaxEventPoints)};
        },
        scan.scan);
    return json_codec::scan_event(seq, scan.observer, scan.sensor(), pose, changed, points);
  });
}

std::shared_ptr<const world::PlanReport> WorldService::plan_report() const { return plan_checks_.report(); }

std::shared_ptr<const world::PlanReport> WorldService::refresh_plan_report() {
  run_command([this] {
    plan_checks_.refresh(*snapshot(), std::nullopt);
    return 0;
  });
  return plan_report();
}

void WorldService::add_to_trim_region(const world::ScanObservation& scan) {
  // A cell more than the event's region: the trim probes a 3×3 neighbourhood.
  const auto box = grid_.changed_region(scan, 3 * grid_.resolution_m());
  const world::Box seen{box.min().x(), box.min().y(), box.max().x(), box.max().y()};
  std::lock_guard lock(trim_mutex_);
  if (!trim_region_) trim_region_ = seen;
  trim_region_ = world::Box{std::min(trim_region_->x0, seen.x0), std::min(trim_region_->y0, seen.y0),
                            std::max(trim_region_->x1, seen.x1), std::max(trim_region_->y1, seen.y1)};
}

void WorldService::trim_now(std::int64_t scan_seq, const world::Box& region) {
  try {
    auto p = prepare_trim(region);
    if (!p) return;
    const auto payload = trim_payload(scan_seq);
    commit_prepared(*p, [&] { store_.commit_observation(p->update, p->observation, payload); });
    auto live = event_log_.begin();
    finish_update(std::move(*p), live);
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::error, "grid_trim",
                        "the grid trim of scan " + std::to_string(scan_seq) + " was not applied: " + e.what());
  }
}

std::optional<WorldService::PreparedUpdate> WorldService::prepare_trim(const world::Box& region) {
  try {
    auto p = own_observation(head(), kTrimObserver, "grid", "grid");
    std::vector<world::GridShares> checked;
    grid_.read([&](const fusion::OccupancyGrid& grid) {
      const double resolution = grid.resolution_m();
      fusion::OccupancyGrid::CellReader cells(grid);  // the samples of an element lie in a few tiles
      const auto probe = grid_element_probe(cells, resolution);
      auto trim = options_.grid_trim;
      trim.step_m = resolution;
      auto trimmed = world::trim_to_grid(*p.base, region, probe, p.seq, p.observation.observer, trim);
      p.update = std::move(trimmed.update);
      checked = std::move(trimmed.checked);
    });
    // The plan's edges the same scans could see: the evidence of missing walls follows the grid.
    plan_checks_.refresh(*p.base, region);
    // The trimmed elements' facts first (that drops their old element_grid/3), then what the grid said of every
    // element checked: the rules' prune/3 may remove what the grid backs nowhere.
    std::vector<rules::ElementFacts> upserts;
    for (auto number : p.update.changed_elements) upserts.push_back(element_facts(p.update.state.elements.at(number)));
    engine_.update_elements(upserts, {});
    std::vector<rules::ElementGridFacts> grid_facts;
    grid_facts.reserve(checked.size());
    for (const auto& c : checked) grid_facts.push_back({world::element_id(c.number), c.backed, c.contrary});
    engine_.set_element_grid(grid_facts);
    const auto orders = engine_.prune_orders(options_.max_prune_per_update);
    if (!orders.empty()) {
      if (p.update.decisions.empty()) {
        p.update.state.version = p.base->version + 1;
        p.update.state.last_observation_seq = p.seq;
      }
      world::apply_prune(p.update, orders, p.seq, p.observation.observer);
      std::vector<std::string> removed;
      for (auto number : p.update.removed_elements) removed.push_back(world::element_id(number));
      engine_.update_elements({}, removed);
    }
    if (p.update.decisions.empty()) return std::nullopt;
    return p;
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::warning, "grid_trim", std::string("grid trim failed: ") + e.what());
    try {
      sync_all_facts(engine_, *head(), options_.world);  // the rules see the map as decided before the trim
    } catch (const std::exception& again) {
      diagnostics_.report(common::Severity::error, "rules",
                          std::string("rule facts not restored after the failed grid trim: ") + again.what());
    }
  }
  return std::nullopt;
}

std::optional<PrimitivesOutcome> WorldService::extract_grid_lines() {
  return run_command([this] { return extract_grid_lines_on_writer(); });
}

std::optional<PrimitivesOutcome> WorldService::extract_grid_lines_on_writer() {
  const auto raster = grid_.probability_raster();
  if (!raster) return std::nullopt;
  const auto segments = fusion::extract_grid_lines(*raster, options_.grid_lines);
  if (segments.empty()) return std::nullopt;
  world::Observation observation;
  observation.observer = "grid-extractor";
  observation.origin = "grid";
  observation.sensor = "grid";
  for (const auto& segment : segments) observation.segments.push_back({segment});
  return apply_on_writer(std::move(observation), "{\"grid_revision\": " + std::to_string(grid_.revision()) + "}");
}

std::shared_ptr<const world::WorldState> WorldService::snapshot() const { return published_.current(); }

std::optional<MapRemovals> WorldService::removed_since(std::int64_t since, std::int64_t up_to) const {
  return published_.removed_since(since, up_to);
}

PrimitivesOutcome WorldService::apply_on_writer(world::Observation observation, const std::string& payload) {
  auto prepared = prepare_update(std::move(observation));
  commit_prepared(prepared, [&] { store_.commit_observation(prepared.update, prepared.observation, payload); });
  auto live = event_log_.begin();
  return finish_update(std::move(prepared), live);
}

WorldService::PreparedUpdate WorldService::own_observation(std::shared_ptr<const world::WorldState> base,
                                                           std::string observer, std::string origin,
                                                           std::string sensor) {
  PreparedUpdate p;
  p.seq = base->last_observation_seq + 1;
  p.base = std::move(base);
  p.observation.observer = std::move(observer);
  p.observation.origin = std::move(origin);
  p.observation.sensor = std::move(sensor);
  p.observation.received_at_unix_s = now_unix_s();
  return p;
}

WorldService::PreparedUpdate WorldService::prepare_update(world::Observation observation) {
  PreparedUpdate p;
  p.base = head();
  p.seq = p.base->last_observation_seq + 1;
  observation.received_at_unix_s = now_unix_s();
  p.update = world::apply_observation(*p.base, observation, p.seq, options_.world,
                                      [this](const rules::DecisionQuery& q) { return engine_.decide(q); });
  try {
    // The rules' prune/3 sees the map as this update leaves it.
    std::vector<rules::ElementFacts> upserts;
    for (auto number : p.update.changed_elements) upserts.push_back(element_facts(p.update.state.elements.at(number)));
    std::vector<std::string> joined_away;  // elements a join removed
    for (auto number : p.update.removed_elements) joined_away.push_back(world::element_id(number));
    engine_.update_elements(upserts, joined_away);
    const auto orders = engine_.prune_orders(options_.max_prune_per_update);
    if (!orders.empty()) {
      world::apply_prune(p.update, orders, p.seq, observation.observer);
      std::vector<std::string> removed;
      for (auto number : p.update.removed_elements) removed.push_back(world::element_id(number));
      engine_.update_elements({}, removed);
    }
    // Edge facts are in the world frame: a moved object must be seen where it is now by the next rule call.
    if (std::any_of(p.update.decisions.begin(), p.update.decisions.end(),
                    [](const auto& d) { return d.action == rules::Action::rigid_adjust; }))
      engine_.set_floor_plan(object_facts(p.update.state, options_.world));
  } catch (...) {
    sync_all_facts(engine_, *p.base,
                   options_.world);  // nothing was applied: the facts go back to the map decided before
    throw;
  }
  p.observation = std::move(observation);
  return p;
}

void WorldService::commit_prepared(const PreparedUpdate& prepared, const std::function<void()>& commit) {
  try {
    commit();
  } catch (...) {
    sync_all_facts(engine_, *prepared.base,
                   options_.world);  // nothing was applied: the facts go back to the committed map
    throw;
  }
}

PrimitivesOutcome WorldService::finish_update(PreparedUpdate prepared, EventLog::Commit& live,
                                              std::set<std::string> removed_objects) {
  auto& update = prepared.update;
  const auto& observation = prepared.observation;
  const auto seq = prepared.seq;
  std::vector<rules::DecisionFacts> logged;
  for (const auto& d : update.decisions) {
    logged.push_back(decision_facts(d, observation.received_at_unix_s));
    if (d.fallback)
      diagnostics_.report(common::Severity::warning, "decisions",
                          "decision " + std::to_string(d.seq) + " fell back to add: " + d.explanation);
  }
  PrimitivesOutcome outcome{seq, update.state.version, update.decisions, false};
  live.add(events::EventKind::update,
           [&] { return json_codec::update_event(seq, observation.origin, update, removed_objects, options_.world); });
  std::set<std::string> removed;
  for (auto number : update.removed_elements) removed.insert(world::element_id(number));
  published_.publish(std::move(update.state), MapRemovals{std::move(removed), std::move(removed_objects)});
  // Committed and published: the request is answered as applied whatever happens here.
  try {
    engine_.add_decisions(logged, options_.decision_facts_kept);
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::warning, "rules",
                        "decision facts of observation " + std::to_string(seq) + " not kept: " + e.what());
  }
  return outcome;
}

std::int64_t WorldService::load_floor_plan(apriori::FloorPlan plan) {
  return run_command([this, plan = std::move(plan)] {
    const auto current = snapshot();
    auto update = world::apply_floor_plan(*current, plan, options_.world);
    auto new_facts = object_facts(update.state, options_.world);
    store_.commit_floor_plan(update, plan);
    const auto version = update.state.version;
    MapRemovals removed;  // the objects of the old plan that the new one does not have
    removed.objects = world::removed_objects(*current, update.state);
    published_.publish(std::move(update.state), std::move(removed));
    engine_.set_floor_plan(new_facts);
    plan_checks_.refresh(*snapshot(), std::nullopt);
    emit(events::EventKind::floorplan,
         [&] { return json_codec::floorplan_event(version, plan.name, plan.objects.size()); });
    return version;
  });
}

rules::RulesStatus WorldService::rules_status() { return engine_.status(); }

rules::RulesStatus WorldService::reload_rules() {
  return run_command([this] {
    try {
      auto status = engine_.reload();
      plan_checks_.refresh(*snapshot(), std::nullopt, true);  // the new rules' verdicts on the same evidence
      emit(events::EventKind::rules, [&] { return json_codec::rules_event(status); });
      return status;
    } catch (const rules::RuleError&) {
      emit(events::EventKind::rules, [&] { return json_codec::rules_event(engine_.status()); });
      throw;
    }
  });
}

void WorldService::on_rules_changed() {
  try {
    const auto status = reload_rules();
    diagnostics_.report(common::Severity::info, "rules",
                        "rules reloaded (generation " + std::to_string(status.generation) + ", " +
                            std::to_string(status.files.size()) + " files)");
  } catch (const rules::RuleError& e) {
    diagnostics_.report(common::Severity::warning, "rules",
                        std::string("rules edit rejected, the previous rules stay active:\n") + e.what());
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::error, "rules", std::string("rules reload failed: ") + e.what());
  }
}

rules::QueryResult WorldService::query(const std::string& goal, std::size_t max_solutions) {
  return reader_->run([this, goal, max_solutions] { return engine_.query(goal, max_solutions); });
}

DryRunOutcome WorldService::dry_run(const rules::RuleText& candidate, std::size_t count) {
  return reader_->run([this, candidate, count] {
    const auto recorded = store_.latest_decisions(count);
    std::vector<rules::DecisionQuery> queries;
    queries.reserve(recorded.size());
    for (const auto& d : recorded) queries.push_back(d.query());
    const auto answers = engine_.dry_run(candidate, queries);
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

std::vector<world::DecisionRecord> WorldService::decisions(std::int64_t since_seq, std::size_t limit,
                                                           const std::optional<std::string>& element) {
  return store_.decisions(since_seq, limit, element);
}

std::vector<world::DecisionRecord> WorldService::object_decisions(const std::string& object_id, std::size_t limit) {
  return store_.object_decisions(object_id, limit);
}

double WorldService::grid_resolution_m() const { return grid_.resolution_m(); }

std::optional<fusion::GridGeometry> WorldService::grid_bounds() const { return grid_.bounds(); }

GridLayerValues WorldService::grid_layer(fusion::OccupancyGrid::Layer layer, const fusion::GridGeometry& region) const {
  return grid_.layer(layer, region);
}

GridTiles WorldService::grid_tiles() const { return grid_.tiles(); }

std::optional<GridTileValues> WorldService::grid_tile(fusion::OccupancyGrid::Layer layer, std::int64_t tx,
                                                      std::int64_t ty) const {
  return grid_.tile(layer, tx, ty);
}

std::optional<GridTileValues> WorldService::grid_tile_layers(std::int64_t tx, std::int64_t ty) const {
  return grid_.tile_layers(tx, ty);
}

void WorldService::restore_robots() {
  for (auto& journal : store_.robot_journal(robots_.options().track_points)) {
    RobotState robot;
    robot.id = journal.robot;
    robot.scans = std::move(journal.scans);
    robot.primitives = journal.primitives;
    robot.poses = journal.poses;
    robot.first_seen_unix_s = journal.first_seen;
    robot.last_seen_unix_s = journal.last_seen;
    std::optional<RobotPose> from_scan;
    if (journal.last_scan) {
      try {
        from_scan = scan_pose(scan_of(std::move(*journal.last_scan)), journal.last_scan_received_at);
      } catch (const std::exception&) {
        // A payload this build no longer reads: the robot comes back without its scan pose.
      }
    }
    for (auto it = journal.poses_newest_first.rbegin(); it != journal.poses_newest_first.rend(); ++it)
      robot.track.push_back(RobotPose{it->x, it->y, it->theta, it->cov, it->stamp, it->received_at, "reported"});
    const auto* reported = robot.track.empty() ? nullptr : &robot.track.back();
    if (reported && (!from_scan || reported->received_at_unix_s >= from_scan->received_at_unix_s)) {
      robot.pose = *reported;
      robot.stopped = journal.poses_newest_first.front().state == "stopped";
    } else {
      robot.pose = from_scan;
    }
    robots_.restore(std::move(robot));
  }
}

void WorldService::add_robot_event(EventLog::Commit& live, const std::optional<RobotState>& robot) {
  if (!robot) return;
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  live.add(events::EventKind::robot,
           [&] { return json_codec::robot_event(*robot, to_string(robots_.status(*robot, now)), now); });
}

RobotState WorldService::put_robot_pose(const std::string& id, RobotPose pose, bool stopped) {
  pose.received_at_unix_s = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  store_.commit_robot_pose({id, pose.x, pose.y, pose.theta, pose.cov, pose.stamp_s, pose.received_at_unix_s,
                            stopped ? "stopped" : "moving"});
  auto live = event_log_.begin();  // not a map commit: its place is when it is heard
  add_robot_event(live, robots_.on_pose(id, pose, stopped));
  return *robots_.find(id);
}

}  // namespace wm::service
