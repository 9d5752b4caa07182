#include <string>

#include "apriori/floor_plan.h"
#include "server/storage/store.h"
#include "server/storage/store_internal.h"

// The floor plan and where it lies: the plan itself, its placements, the decided plan changes, the georeference.
namespace wm::storage {

using internal::bind_matrix;
using internal::now_unix_s;
using internal::read_matrix;
using internal::run;

std::vector<StoredPlacement> Store::placements() {
  std::lock_guard lock(writer_mutex_);
  std::vector<StoredPlacement> result;
  Statement s(*writer_, "SELECT x, y, theta, scale, cov, rule, decision_seq FROM placements ORDER BY ord");
  while (s.step())
    result.push_back({{s.column_double(0), s.column_double(1), s.column_double(2), s.column_double(3)},
                      read_matrix<Eigen::Matrix4d>(s, 4),
                      s.column_text(5),
                      s.column_int(6)});
  return result;
}

void Store::commit_placement(const ObservationEntry& entry, bool undo) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  write_observation(entry);
  const auto& state = entry.update.state;
  if (undo) {
    writer_->exec("DELETE FROM placements WHERE ord = (SELECT MAX(ord) FROM placements)");
  } else {
    Statement s(*writer_,
                "INSERT INTO placements(x, y, theta, scale, cov, rule, decision_seq, version, created_at) "
                "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)");
    s.bind(1, state.placement.x_m).bind(2, state.placement.y_m).bind(3, state.placement.theta_rad);
    s.bind(4, state.placement.scale);
    bind_matrix(s, 5, state.placement_cov);
    const auto& d = entry.update.decisions.at(0);
    s.bind(6, std::string_view(d.rule)).bind(7, d.seq).bind(8, state.version).bind(9, now_unix_s()).run();
  }
  tx.commit();
}

void Store::commit_plan_change(const ObservationEntry& entry, const std::optional<apriori::FloorPlan>& plan,
                               const std::optional<PlanChangeRecord>& push) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  if (plan) {
    // The objects' rows are numbered by plan order: all of them are written again by write_observation.
    const std::string text = apriori::to_json_text(*plan);
    writer_->exec("DELETE FROM objects");
    run(*writer_, "UPDATE floor_plan SET name = ?1, plan_json = ?2 WHERE id = 1", std::string_view(plan->name),
        std::string_view(text));
  }
  write_observation(entry);
  if (push) {
    std::optional<std::string> before;
    if (push->plan_before) before = apriori::to_json_text(*push->plan_before);
    Statement s(*writer_,
                "INSERT INTO plan_changes(change_id, verdict, plan_before, decision_seq, version, created_at) "
                "VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
    s.bind(1, std::string_view(push->change_id)).bind(2, std::string_view(push->verdict)).bind(3, before);
    s.bind(4, entry.update.decisions.at(0).seq).bind(5, entry.update.state.version).bind(6, now_unix_s()).run();
  } else {
    writer_->exec("DELETE FROM plan_changes WHERE ord = (SELECT MAX(ord) FROM plan_changes)");
  }
  write_counters(entry.update.state);
  tx.commit();
}

std::vector<Store::PlanChangeRecord> Store::plan_changes() {
  std::lock_guard lock(writer_mutex_);
  Statement s(*writer_, "SELECT change_id, verdict, plan_before, decision_seq FROM plan_changes ORDER BY ord");
  std::vector<PlanChangeRecord> result;
  while (s.step()) {
    PlanChangeRecord r;
    r.change_id = s.column_text(0);
    r.verdict = s.column_text(1);
    if (const auto text = s.column_optional_text(2)) r.plan_before = apriori::parse_floor_plan_json(*text);
    r.decision_seq = s.column_int(3);
    result.push_back(std::move(r));
  }
  return result;
}

void Store::commit_georeference(const world::WorldState& state) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  if (state.georeference) {
    run(*writer_,
        "INSERT INTO georeference(id, latitude, longitude, heading) VALUES (1, ?1, ?2, ?3) ON CONFLICT(id) DO UPDATE "
        "SET latitude = excluded.latitude, longitude = excluded.longitude, heading = excluded.heading",
        state.georeference->latitude_deg, state.georeference->longitude_deg, state.georeference->heading_deg);
  } else {
    writer_->exec("DELETE FROM georeference");
  }
  write_counters(state);
  tx.commit();
}

void Store::commit_floor_plan(const world::UpdateResult& update, const apriori::FloorPlan& plan) {
  std::lock_guard lock(writer_mutex_);
  const std::string text = apriori::to_json_text(plan);
  Transaction tx(*writer_);
  writer_->exec("DELETE FROM objects");
  run(*writer_,
      "INSERT INTO floor_plan(id, name, plan_json, loaded_version) VALUES (1, ?1, ?2, ?3) "
      "ON CONFLICT(id) DO UPDATE SET name = excluded.name, plan_json = excluded.plan_json, "
      "loaded_version = excluded.loaded_version",
      std::string_view(plan.name), std::string_view(text), update.state.version);
  write_objects(update);
  write_counters(update.state);
  tx.commit();
}

}  // namespace wm::storage
