#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "apriori/floor_plan.h"
#include "rules/action.h"
#include "server/storage/store.h"
#include "server/storage/store_internal.h"

// The world state: its load, and each observation's effects (elements, objects, decisions, counters); the
// decision log's reads.
namespace wm::storage {

using internal::bind_all;
using internal::bind_doubles;
using internal::bind_matrix;
using internal::now_unix_s;
using internal::read_matrix;
using internal::run;

world::WorldState Store::load(const world::WorldOptions& options) {
  std::lock_guard lock(writer_mutex_);
  world::WorldState state;
  {
    Statement s(*writer_, "SELECT key, value FROM meta");
    while (s.step()) {
      const auto key = s.column_text(0);
      const auto value = s.column_int(1);
      if (key == "version")
        state.version = value;
      else if (key == "next_element_number")
        state.next_element_number = value;
      else if (key == "last_observation_seq")
        state.last_observation_seq = value;
      else if (key == "last_decision_seq")
        state.last_decision_seq = value;
    }
  }
  if (const auto history = placements(); !history.empty()) {
    state.placement = history.back().placement;
    state.placement_cov = history.back().cov;
  }
  {
    Statement s(*writer_, "SELECT latitude, longitude, heading FROM georeference WHERE id = 1");
    if (s.step())
      state.georeference = apriori::Georeference{s.column_double(0), s.column_double(1), s.column_double(2)};
  }
  {
    Statement s(*writer_, "SELECT name, plan_json FROM floor_plan WHERE id = 1");
    if (s.step()) {
      const auto plan = apriori::parse_floor_plan_json(s.column_text(1));
      state.plan_name = plan.name;
      state.objects = world::ObjectTable(world::make_objects(plan, options, 0, state.placement));
    }
  }
  {
    Statement s(
        *writer_,
        "SELECT ord, id, x, y, theta, pose_cov, confirmations, adjustments, updated_version FROM objects ORDER BY ord");
    while (s.step()) {
      const auto ord = static_cast<std::size_t>(s.column_int(0));
      if (ord >= state.objects.size() || state.objects[ord].plan->id != s.column_text(1))
        throw StorageError("objects table does not match the stored floor plan");
      auto object = state.objects[ord];
      fusion::Pose2D pose{s.column_double(2), s.column_double(3), s.column_double(4)};
      object.body = fusion::RigidObject(pose, read_matrix<Eigen::Matrix3d>(s, 5), object.body.edges());
      object.confirmations = s.column_int(6);
      object.adjustments = s.column_int(7);
      object.updated_version = s.column_int(8);
      state.objects.put(ord, std::move(object));
    }
  }
  {
    Statement s(*writer_,
                "SELECT number, rho, phi, cov, t0, t1, support, source, observer, created_version, updated_version, "
                "updated_at, moments, facing, both_ways FROM elements ORDER BY number");
    while (s.step()) {
      world::Element e;
      e.number = s.column_int(0);
      e.segment.line.rho_m = s.column_double(1);
      e.segment.line.phi_rad = s.column_double(2);
      e.segment.line.cov = read_matrix<Eigen::Matrix2d>(s, 3);
      e.segment.t0_m = s.column_double(4);
      e.segment.t1_m = s.column_double(5);
      e.support = s.column_int(6);
      e.origin = s.column_text(7);  // column "source"
      e.observer = s.column_text(8);
      e.created_version = s.column_int(9);
      e.updated_version = s.column_int(10);
      e.updated_at_unix_s = s.column_double(11);
      const auto moments = s.column_doubles(12);
      if (moments.empty()) {
        e.moments = fusion::SegmentMoments::of(e.segment);
      } else if (moments.size() == 6) {
        std::array<double, 6> values;
        std::copy(moments.begin(), moments.end(), values.begin());
        e.moments = fusion::SegmentMoments::from_array(values);
      } else {
        throw StorageError("corrupt element moments in database");
      }
      e.facing_rad = s.column_optional_double(13);
      e.both_ways = s.column_int(14) != 0;
      state.elements.put(std::move(e));
    }
  }
  return state;
}

void Store::mark_removed() {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  run(*writer_, "INSERT INTO meta(key, value) VALUES ('removed', 1) ON CONFLICT(key) DO UPDATE SET value = 1");
  tx.commit();
}

bool Store::marked_removed() {
  std::lock_guard lock(writer_mutex_);
  Statement s(*writer_, "SELECT 1 FROM meta WHERE key = 'removed'");
  return s.step();
}

void Store::write_counters(const world::WorldState& state) {
  Statement s(*writer_,
              "INSERT INTO meta(key, value) VALUES (?1, ?2) ON CONFLICT(key) DO UPDATE SET value = excluded.value");
  s.bind(1, std::string_view("version")).bind(2, state.version).run();
  s.bind(1, std::string_view("next_element_number")).bind(2, state.next_element_number).run();
  s.bind(1, std::string_view("last_observation_seq")).bind(2, state.last_observation_seq).run();
  s.bind(1, std::string_view("last_decision_seq")).bind(2, state.last_decision_seq).run();
}

void Store::write_objects(const world::UpdateResult& update) {
  Statement s(
      *writer_,
      "INSERT INTO objects(ord, id, x, y, theta, pose_cov, confirmations, adjustments, updated_version) "
      "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9) ON CONFLICT(ord) DO UPDATE SET id = excluded.id, x = excluded.x, "
      "y = excluded.y, theta = excluded.theta, pose_cov = excluded.pose_cov, confirmations = excluded.confirmations, "
      "adjustments = excluded.adjustments, updated_version = excluded.updated_version");
  for (auto index : update.changed_objects) {
    const auto& o = update.state.objects.at(index);
    const auto& pose = o.body.pose();
    s.bind(1, static_cast<std::int64_t>(index)).bind(2, std::string_view(o.plan->id));
    s.bind(3, pose.x_m).bind(4, pose.y_m).bind(5, pose.theta_rad);
    bind_matrix(s, 6, o.body.pose_cov());
    s.bind(7, o.confirmations).bind(8, o.adjustments).bind(9, o.updated_version).run();
  }
}

void Store::insert_observation(std::int64_t seq, std::string_view kind, const std::string& observer, double stamp,
                               std::string_view payload) {
  run(*writer_,
      "INSERT INTO observations(seq, kind, observer, stamp, received_at, payload) VALUES (?1, ?2, ?3, ?4, ?5, ?6)", seq,
      kind, std::string_view(observer), stamp, now_unix_s(), payload);
}

void Store::commit_observation(const world::UpdateResult& update, const world::Observation& observation,
                               std::string_view payload_json, const std::optional<RequestRecord>& request) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  write_observation({update, observation, payload_json});
  if (request) write_request(*request);
  tx.commit();
}

void Store::write_observation(const ObservationEntry& entry) {
  const auto& update = entry.update;
  insert_observation(update.state.last_observation_seq, entry.observation.origin, entry.observation.observer,
                     entry.observation.stamp_s, entry.payload);
  {
    Statement s(
        *writer_,
        "INSERT INTO elements(number, rho, phi, cov, t0, t1, support, source, observer, created_version, "
        "updated_version, updated_at, moments, facing, both_ways) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, "
        "?11, ?12, ?13, ?14, ?15) "
        "ON CONFLICT(number) DO UPDATE SET "
        "rho = excluded.rho, phi = excluded.phi, cov = excluded.cov, t0 = excluded.t0, t1 = excluded.t1, "
        "support = excluded.support, updated_version = excluded.updated_version, updated_at = excluded.updated_at, "
        "moments = excluded.moments, facing = excluded.facing, both_ways = excluded.both_ways");
    for (auto number : update.changed_elements) {
      const auto& e = update.state.elements.at(number);
      s.bind(1, e.number).bind(2, e.segment.line.rho_m).bind(3, e.segment.line.phi_rad);
      bind_matrix(s, 4, e.segment.line.cov);
      s.bind(5, e.segment.t0_m).bind(6, e.segment.t1_m).bind(7, e.support);
      s.bind(8, std::string_view(e.origin)).bind(9, std::string_view(e.observer));
      const auto moments = e.moments.to_array();
      bind_doubles(s, 13, std::vector<double>(moments.begin(), moments.end()));
      s.bind(14, e.facing_rad).bind(15, static_cast<std::int64_t>(e.both_ways ? 1 : 0));
      s.bind(10, e.created_version).bind(11, e.updated_version).bind(12, e.updated_at_unix_s).run();
    }
  }
  {
    Statement s(*writer_, "DELETE FROM elements WHERE number = ?1");
    for (auto number : update.removed_elements) s.bind(1, number).run();
  }
  write_objects(update);
  {
    Statement s(
        *writer_,
        "INSERT INTO decisions(seq, observation_seq, idx, action, rule, explanation, element, object, "
        "mahalanobis_sq, fallback, observer, p0x, p0y, p1x, p1y, origin, sensor, matched_element, matched_object, "
        "observed, before, after) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20, ?21, ?22)");
    for (const auto& d : update.decisions) {
      s.bind(1, d.seq).bind(2, d.observation_seq).bind(3, d.index);
      s.bind(4, rules::wire_name(d.action)).bind(5, std::string_view(d.rule)).bind(6, std::string_view(d.explanation));
      s.bind(7, d.element).bind(8, d.object).bind(9, d.mahalanobis_sq).bind(10, std::int64_t{d.fallback});
      s.bind(11, std::string_view(d.observer));
      s.bind(12, d.p0.x()).bind(13, d.p0.y()).bind(14, d.p1.x()).bind(15, d.p1.y());
      s.bind(16, std::string_view(d.origin)).bind(17, std::string_view(d.sensor));
      s.bind(18, d.matched_element).bind(19, d.matched_object);
      const std::vector<double> observed{
          d.rho_m, d.phi_rad, d.observed_cov(0, 0), d.observed_cov(0, 1), d.observed_cov(1, 0), d.observed_cov(1, 1)};
      bind_doubles(s, 20, observed);
      bind_doubles(s, 21, d.before);
      bind_doubles(s, 22, d.after);
      s.run();
    }
  }
  write_counters(update.state);
}

namespace {

constexpr const char* kDecisionColumns =
    "SELECT seq, observation_seq, idx, action, rule, explanation, element, object, mahalanobis_sq, fallback, "
    "observer, p0x, p0y, p1x, p1y, origin, sensor, matched_element, matched_object, observed, before, after "
    "FROM decisions ";

world::DecisionRecord read_decision(const Statement& s) {
  world::DecisionRecord d;
  d.seq = s.column_int(0);
  d.observation_seq = s.column_int(1);
  d.index = s.column_int(2);
  const std::string action = s.column_text(3);
  const auto parsed = rules::parse_action(action);
  if (!parsed)
    throw std::runtime_error("decision log: unknown action '" + action + "' (database written by a newer server?)");
  d.action = *parsed;
  d.rule = s.column_text(4);
  d.explanation = s.column_text(5);
  d.element = s.column_optional_text(6);
  d.object = s.column_optional_text(7);
  d.mahalanobis_sq = s.column_optional_double(8);
  d.fallback = s.column_int(9) != 0;
  d.observer = s.column_text(10);
  d.p0 = {s.column_double(11), s.column_double(12)};
  d.p1 = {s.column_double(13), s.column_double(14)};
  d.origin = s.column_text(15);
  d.sensor = s.column_text(16);
  d.matched_element = s.column_optional_text(17);
  d.matched_object = s.column_optional_text(18);
  const auto observed = s.column_doubles(19);
  if (observed.size() == 6) {
    d.rho_m = observed[0];
    d.phi_rad = observed[1];
    d.observed_cov << observed[2], observed[3], observed[4], observed[5];
  } else {  // a v1 row: the line through the stored endpoints
    const Eigen::Vector2d dir = (d.p1 - d.p0).normalized();
    const Eigen::Vector2d normal(-dir.y(), dir.x());
    d.rho_m = normal.dot(d.p0);
    d.phi_rad = std::atan2(normal.y(), normal.x());
  }
  d.before = s.column_doubles(20);
  d.after = s.column_doubles(21);
  return d;
}

// The decisions `where` (a WHERE clause with its ORDER BY and LIMIT) selects, its parameters bound in order.
template <typename... Values>
std::vector<world::DecisionRecord> select_decisions(Connection& db, std::string_view where, const Values&... values) {
  Statement s(db, std::string(kDecisionColumns) + std::string(where));
  bind_all(s, values...);
  std::vector<world::DecisionRecord> result;
  while (s.step()) result.push_back(read_decision(s));
  return result;
}

}  // namespace

std::vector<world::DecisionRecord> Store::decisions(std::int64_t since_seq, std::size_t limit,
                                                    const std::optional<std::string>& element) {
  std::lock_guard lock(reader_mutex_);
  return select_decisions(
      *reader_,
      "WHERE seq > ?1 AND (CAST(?2 AS TEXT) IS NULL OR element = ?2 OR matched_element = ?2) ORDER BY seq LIMIT ?3",
      since_seq, element, static_cast<std::int64_t>(limit));
}

std::vector<world::DecisionRecord> Store::observation_decisions(std::int64_t observation_seq) {
  std::lock_guard lock(reader_mutex_);
  return select_decisions(*reader_, "WHERE observation_seq = ?1 ORDER BY seq", observation_seq);
}

std::vector<world::DecisionRecord> Store::object_decisions(const std::string& object_id, std::size_t limit) {
  std::lock_guard lock(reader_mutex_);
  return select_decisions(*reader_, "WHERE object = ?1 OR matched_object = ?1 ORDER BY seq LIMIT ?2",
                          std::string_view(object_id), static_cast<std::int64_t>(limit));
}

std::vector<world::DecisionRecord> Store::latest_decisions(std::size_t count) {
  std::lock_guard lock(reader_mutex_);
  auto result =
      select_decisions(*reader_, "WHERE idx >= 0 ORDER BY seq DESC LIMIT ?1", static_cast<std::int64_t>(count));
  std::reverse(result.begin(), result.end());
  return result;
}

}  // namespace wm::storage
