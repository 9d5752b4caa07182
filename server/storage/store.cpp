#include "server/storage/store.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>

#include "apriori/floor_plan.h"
#include "rules/action.h"

namespace wm::storage {
namespace {

// Each entry moves the schema from version i to i+1. Never edit a shipped entry: append a new one.
constexpr const char* kMigrations[] = {
    R"sql(
CREATE TABLE meta(key TEXT PRIMARY KEY, value INTEGER NOT NULL);
CREATE TABLE floor_plan(id INTEGER PRIMARY KEY CHECK (id = 1), name TEXT NOT NULL, plan_json TEXT NOT NULL,
                        loaded_version INTEGER NOT NULL);
CREATE TABLE objects(ord INTEGER PRIMARY KEY, id TEXT NOT NULL UNIQUE, x REAL NOT NULL, y REAL NOT NULL,
                     theta REAL NOT NULL, pose_cov BLOB NOT NULL, confirmations INTEGER NOT NULL,
                     adjustments INTEGER NOT NULL, updated_version INTEGER NOT NULL);
CREATE TABLE elements(number INTEGER PRIMARY KEY, rho REAL NOT NULL, phi REAL NOT NULL, cov BLOB NOT NULL,
                      t0 REAL NOT NULL, t1 REAL NOT NULL, support INTEGER NOT NULL, source TEXT NOT NULL,
                      observer TEXT NOT NULL, created_version INTEGER NOT NULL, updated_version INTEGER NOT NULL);
CREATE TABLE observations(seq INTEGER PRIMARY KEY, kind TEXT NOT NULL, observer TEXT NOT NULL, stamp REAL NOT NULL,
                          received_at REAL NOT NULL, payload TEXT NOT NULL);
CREATE TABLE decisions(seq INTEGER PRIMARY KEY, observation_seq INTEGER NOT NULL REFERENCES observations(seq),
                       idx INTEGER NOT NULL, action TEXT NOT NULL, rule TEXT NOT NULL, explanation TEXT NOT NULL,
                       element TEXT, object TEXT, mahalanobis_sq REAL, fallback INTEGER NOT NULL,
                       observer TEXT NOT NULL, p0x REAL NOT NULL, p0y REAL NOT NULL, p1x REAL NOT NULL, p1y REAL NOT NULL);
CREATE INDEX decisions_by_element ON decisions(element);
)sql",
    // v2: what explanations, dry runs and age-based pruning need.
    R"sql(
ALTER TABLE elements ADD COLUMN updated_at REAL NOT NULL DEFAULT 0;
ALTER TABLE decisions ADD COLUMN origin TEXT NOT NULL DEFAULT 'client';
ALTER TABLE decisions ADD COLUMN sensor TEXT NOT NULL DEFAULT 'unknown';
ALTER TABLE decisions ADD COLUMN matched_element TEXT;
ALTER TABLE decisions ADD COLUMN matched_object TEXT;
ALTER TABLE decisions ADD COLUMN observed BLOB;
ALTER TABLE decisions ADD COLUMN before BLOB;
ALTER TABLE decisions ADD COLUMN after BLOB;
CREATE INDEX decisions_by_matched_element ON decisions(matched_element);
)sql",
    // v3: occupancy grids. Scans are journaled one by one; tiles are flushed in batches with the last scan
    // they include, and scans after it are replayed at start.
    R"sql(
CREATE TABLE scans(seq INTEGER PRIMARY KEY, observer TEXT NOT NULL, sensor TEXT NOT NULL, stamp REAL NOT NULL,
                   received_at REAL NOT NULL, payload TEXT NOT NULL);
CREATE TABLE grid_tiles(tx INTEGER NOT NULL, ty INTEGER NOT NULL, log_odds BLOB NOT NULL, m_occupied BLOB NOT NULL,
                        m_empty BLOB NOT NULL, conflict BLOB NOT NULL, PRIMARY KEY (tx, ty));
CREATE TABLE grid_meta(id INTEGER PRIMARY KEY CHECK (id = 1), resolution REAL NOT NULL, tile_size INTEGER NOT NULL,
                       through_scan_seq INTEGER NOT NULL);
)sql",
    // v4: a scan and the observation of its extracted lines commit together (scans.lines_seq links them;
    // filled here for older scans from the observation's payload {"scan": N}); request ids (Idempotency-Key)
    // with what their request produced, committed with its effect; decisions found by observation.
    R"sql(
ALTER TABLE scans ADD COLUMN lines_seq INTEGER;
UPDATE scans SET lines_seq = o.seq FROM observations o
 WHERE o.kind = 'scan' AND o.payload LIKE '{"scan": %}'
   AND scans.seq = CAST(substr(o.payload, 10, length(o.payload) - 10) AS INTEGER);
CREATE TABLE requests(ord INTEGER PRIMARY KEY, request_id TEXT NOT NULL UNIQUE, kind TEXT NOT NULL,
                      body_hash INTEGER NOT NULL, seq INTEGER NOT NULL, version INTEGER NOT NULL,
                      grid_revision INTEGER NOT NULL, lines_seq INTEGER, created_at REAL NOT NULL);
CREATE INDEX decisions_by_observation ON decisions(observation_seq);
)sql",
    // v5: what an element was built from (fusion::SegmentMoments), for the straightness test of later merges;
    // NULL for elements stored before, which are read as if seen once.
    R"sql(
ALTER TABLE elements ADD COLUMN moments BLOB;
)sql",
    // v6: the plan's placement in the world, a stack (the top row is in force; undo removes it), each row with the
    // decision that logged it; the world frame's georeference.
    R"sql(
CREATE TABLE placements(ord INTEGER PRIMARY KEY, x REAL NOT NULL, y REAL NOT NULL, theta REAL NOT NULL,
                        scale REAL NOT NULL, cov BLOB NOT NULL, rule TEXT NOT NULL, decision_seq INTEGER NOT NULL,
                        version INTEGER NOT NULL, created_at REAL NOT NULL);
CREATE TABLE georeference(id INTEGER PRIMARY KEY CHECK (id = 1), latitude REAL NOT NULL, longitude REAL NOT NULL,
                          heading REAL NOT NULL);
)sql",
    // v7: poses robots report without a scan (PUT /api/v1/robots/{id}/pose), journaled; the robots' scans and
    // primitives are already in scans and observations.
    R"sql(
CREATE TABLE robot_poses(seq INTEGER PRIMARY KEY, robot TEXT NOT NULL, x REAL NOT NULL, y REAL NOT NULL,
                         theta REAL NOT NULL, cov BLOB, stamp REAL NOT NULL, received_at REAL NOT NULL,
                         state TEXT NOT NULL);
CREATE INDEX robot_poses_by_robot ON robot_poses(robot, seq);
CREATE INDEX scans_by_observer ON scans(observer, seq);
)sql",
    // v8: what people decided about the changes listed between plan and building, a stack (undo removes the top
    // row): an accepted change keeps the plan as it was before it, so an undo can put that plan back. The beams
    // that passed through or ended on each plan edge (uint32 per 10 cm bin), flushed with the grid's tiles: like
    // them, rebuilt past the flush from the scan journal at start.
    R"sql(
CREATE TABLE plan_changes(ord INTEGER PRIMARY KEY, change_id TEXT NOT NULL, verdict TEXT NOT NULL,
                          plan_before TEXT, decision_seq INTEGER NOT NULL, version INTEGER NOT NULL,
                          created_at REAL NOT NULL);
CREATE TABLE edge_beams(object TEXT NOT NULL, edge INTEGER NOT NULL, x0 REAL NOT NULL, y0 REAL NOT NULL,
                        x1 REAL NOT NULL, y1 REAL NOT NULL, through BLOB NOT NULL, ended BLOB NOT NULL,
                        PRIMARY KEY(object, edge));
)sql",
    // v9: the side an element's wall was seen from (the direction of its normal toward the sensor, radians), NULL
    // when not known (posted segments, grid lines, elements stored before).
    R"sql(
ALTER TABLE elements ADD COLUMN facing REAL;
)sql",
};
constexpr int kMigrationCount = static_cast<int>(sizeof(kMigrations) / sizeof(kMigrations[0]));
static_assert(kMigrationCount == Store::kSchemaVersion);

double now_unix_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// Binds `values` to ?1, ?2, ... in order (std::int64_t, double, std::string_view or their optionals).
template <typename... Values>
Statement& bind_all(Statement& s, const Values&... values) {
  int index = 0;
  (s.bind(++index, values), ...);
  return s;
}

// Runs one statement that returns no rows, with its parameters. @throw StorageError.
template <typename... Values>
void run(Connection& db, std::string_view sql, const Values&... values) {
  Statement s(db, sql);
  bind_all(s, values...).run();
}

// The first column of the first row of a query that returns one (COUNT, MAX, PRAGMA). @throw StorageError.
std::int64_t query_int(Connection& db, std::string_view sql) {
  Statement s(db, sql);
  s.step();
  return s.column_int(0);
}

template <typename Matrix>
void bind_matrix(Statement& s, int index, const Matrix& m) {
  s.bind_blob(index, m.data(), sizeof(double) * static_cast<std::size_t>(m.size()));
}

void bind_doubles(Statement& s, int index, const std::vector<double>& values) {
  if (values.empty()) {
    s.bind_null(index);
  } else {
    s.bind_blob(index, values.data(), sizeof(double) * values.size());
  }
}

template <typename Matrix>
Matrix read_matrix(const Statement& s, int column) {
  const auto values = s.column_doubles(column);
  Matrix m;
  if (values.size() != static_cast<std::size_t>(m.size())) throw StorageError("corrupt matrix in database");
  for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = values[static_cast<std::size_t>(i)];
  return m;
}

}  // namespace

Store::Store(const StoreOptions& options)
    : options_(options), writer_(options.path, true), reader_(options.path, false) {
  writer_.exec("PRAGMA journal_mode=WAL");
  writer_.exec(options_.synchronous_full ? "PRAGMA synchronous=FULL" : "PRAGMA synchronous=NORMAL");
  writer_.exec("PRAGMA foreign_keys=ON");
  migrate();
}

int Store::schema_version() {
  std::lock_guard lock(writer_mutex_);
  return static_cast<int>(query_int(writer_, "PRAGMA user_version"));
}

void Store::migrate() {
  const int found = schema_version();
  if (found > kSchemaVersion)
    throw StorageError("database '" + options_.path + "' has schema version " + std::to_string(found) +
                       ", newer than this build's " + std::to_string(kSchemaVersion) + ": refusing to touch it");
  for (int v = found; v < kSchemaVersion; ++v) {
    Transaction tx(writer_);
    writer_.exec(kMigrations[v]);
    writer_.exec("PRAGMA user_version = " + std::to_string(v + 1));
    tx.commit();
  }
}

world::WorldState Store::load(const world::WorldOptions& options) {
  std::lock_guard lock(writer_mutex_);
  world::WorldState state;
  {
    Statement s(writer_, "SELECT key, value FROM meta");
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
    Statement s(writer_, "SELECT latitude, longitude, heading FROM georeference WHERE id = 1");
    if (s.step())
      state.georeference = apriori::Georeference{s.column_double(0), s.column_double(1), s.column_double(2)};
  }
  {
    Statement s(writer_, "SELECT name, plan_json FROM floor_plan WHERE id = 1");
    if (s.step()) {
      const auto plan = apriori::parse_floor_plan_json(s.column_text(1));
      state.plan_name = plan.name;
      state.objects = world::ObjectTable(world::make_objects(plan, options, 0, state.placement));
    }
  }
  {
    Statement s(
        writer_,
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
    Statement s(writer_,
                "SELECT number, rho, phi, cov, t0, t1, support, source, observer, created_version, updated_version, "
                "updated_at, moments, facing FROM elements ORDER BY number");
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
      state.elements.put(std::move(e));
    }
  }
  return state;
}

void Store::write_counters(const world::WorldState& state) {
  Statement s(writer_,
              "INSERT INTO meta(key, value) VALUES (?1, ?2) ON CONFLICT(key) DO UPDATE SET value = excluded.value");
  s.bind(1, std::string_view("version")).bind(2, state.version).run();
  s.bind(1, std::string_view("next_element_number")).bind(2, state.next_element_number).run();
  s.bind(1, std::string_view("last_observation_seq")).bind(2, state.last_observation_seq).run();
  s.bind(1, std::string_view("last_decision_seq")).bind(2, state.last_decision_seq).run();
}

void Store::write_objects(const world::UpdateResult& update) {
  Statement s(
      writer_,
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
  run(writer_,
      "INSERT INTO observations(seq, kind, observer, stamp, received_at, payload) VALUES (?1, ?2, ?3, ?4, ?5, ?6)", seq,
      kind, std::string_view(observer), stamp, now_unix_s(), payload);
}

void Store::commit_observation(const world::UpdateResult& update, const world::Observation& observation,
                               std::string_view payload_json, const std::optional<RequestRecord>& request) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(writer_);
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
        writer_,
        "INSERT INTO elements(number, rho, phi, cov, t0, t1, support, source, observer, created_version, "
        "updated_version, updated_at, moments, facing) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, "
        "?13, ?14) "
        "ON CONFLICT(number) DO UPDATE SET "
        "rho = excluded.rho, phi = excluded.phi, cov = excluded.cov, t0 = excluded.t0, t1 = excluded.t1, "
        "support = excluded.support, updated_version = excluded.updated_version, updated_at = excluded.updated_at, "
        "moments = excluded.moments, facing = excluded.facing");
    for (auto number : update.changed_elements) {
      const auto& e = update.state.elements.at(number);
      s.bind(1, e.number).bind(2, e.segment.line.rho_m).bind(3, e.segment.line.phi_rad);
      bind_matrix(s, 4, e.segment.line.cov);
      s.bind(5, e.segment.t0_m).bind(6, e.segment.t1_m).bind(7, e.support);
      s.bind(8, std::string_view(e.origin)).bind(9, std::string_view(e.observer));
      const auto moments = e.moments.to_array();
      bind_doubles(s, 13, std::vector<double>(moments.begin(), moments.end()));
      s.bind(14, e.facing_rad);
      s.bind(10, e.created_version).bind(11, e.updated_version).bind(12, e.updated_at_unix_s).run();
    }
  }
  {
    Statement s(writer_, "DELETE FROM elements WHERE number = ?1");
    for (auto number : update.removed_elements) s.bind(1, number).run();
  }
  write_objects(update);
  {
    Statement s(
        writer_,
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

void Store::write_request(const RequestRecord& r) {
  run(writer_,
      "INSERT INTO requests(request_id, kind, body_hash, seq, version, grid_revision, lines_seq, created_at) "
      "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
      std::string_view(r.request_id), std::string_view(r.kind), r.body_hash, r.seq, r.version, r.grid_revision,
      r.lines_seq, now_unix_s());
  // Bounded by count: rows are numbered in insertion order, so the oldest go in one range delete.
  run(writer_, "DELETE FROM requests WHERE ord <= ?1", writer_.last_insert_rowid() - options_.request_ids_kept);
}

std::optional<RequestRecord> Store::find_request(const std::string& request_id) {
  std::lock_guard lock(writer_mutex_);
  Statement s(writer_,
              "SELECT kind, body_hash, seq, version, grid_revision, lines_seq FROM requests WHERE request_id = ?1");
  s.bind(1, std::string_view(request_id));
  if (!s.step()) return std::nullopt;
  RequestRecord r;
  r.request_id = request_id;
  r.kind = s.column_text(0);
  r.body_hash = s.column_int(1);
  r.seq = s.column_int(2);
  r.version = s.column_int(3);
  r.grid_revision = s.column_int(4);
  r.lines_seq = s.column_optional_int(5);
  return r;
}

std::vector<StoredPlacement> Store::placements() {
  std::lock_guard lock(writer_mutex_);
  std::vector<StoredPlacement> result;
  Statement s(writer_, "SELECT x, y, theta, scale, cov, rule, decision_seq FROM placements ORDER BY ord");
  while (s.step())
    result.push_back({{s.column_double(0), s.column_double(1), s.column_double(2), s.column_double(3)},
                      read_matrix<Eigen::Matrix4d>(s, 4),
                      s.column_text(5),
                      s.column_int(6)});
  return result;
}

void Store::commit_placement(const ObservationEntry& entry, bool undo) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(writer_);
  write_observation(entry);
  const auto& state = entry.update.state;
  if (undo) {
    writer_.exec("DELETE FROM placements WHERE ord = (SELECT MAX(ord) FROM placements)");
  } else {
    Statement s(writer_,
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
  Transaction tx(writer_);
  if (plan) {
    // The objects' rows are numbered by plan order: all of them are written again by write_observation.
    const std::string text = apriori::to_json_text(*plan);
    writer_.exec("DELETE FROM objects");
    run(writer_, "UPDATE floor_plan SET name = ?1, plan_json = ?2 WHERE id = 1", std::string_view(plan->name),
        std::string_view(text));
  }
  write_observation(entry);
  if (push) {
    std::optional<std::string> before;
    if (push->plan_before) before = apriori::to_json_text(*push->plan_before);
    Statement s(writer_,
                "INSERT INTO plan_changes(change_id, verdict, plan_before, decision_seq, version, created_at) "
                "VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
    s.bind(1, std::string_view(push->change_id)).bind(2, std::string_view(push->verdict)).bind(3, before);
    s.bind(4, entry.update.decisions.at(0).seq).bind(5, entry.update.state.version).bind(6, now_unix_s()).run();
  } else {
    writer_.exec("DELETE FROM plan_changes WHERE ord = (SELECT MAX(ord) FROM plan_changes)");
  }
  write_counters(entry.update.state);
  tx.commit();
}

std::vector<Store::PlanChangeRecord> Store::plan_changes() {
  std::lock_guard lock(writer_mutex_);
  Statement s(writer_, "SELECT change_id, verdict, plan_before, decision_seq FROM plan_changes ORDER BY ord");
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
  Transaction tx(writer_);
  if (state.georeference) {
    run(writer_,
        "INSERT INTO georeference(id, latitude, longitude, heading) VALUES (1, ?1, ?2, ?3) ON CONFLICT(id) DO UPDATE "
        "SET latitude = excluded.latitude, longitude = excluded.longitude, heading = excluded.heading",
        state.georeference->latitude_deg, state.georeference->longitude_deg, state.georeference->heading_deg);
  } else {
    writer_.exec("DELETE FROM georeference");
  }
  write_counters(state);
  tx.commit();
}

void Store::commit_floor_plan(const world::UpdateResult& update, const apriori::FloorPlan& plan) {
  std::lock_guard lock(writer_mutex_);
  const std::string text = apriori::to_json_text(plan);
  Transaction tx(writer_);
  writer_.exec("DELETE FROM objects");
  run(writer_,
      "INSERT INTO floor_plan(id, name, plan_json, loaded_version) VALUES (1, ?1, ?2, ?3) "
      "ON CONFLICT(id) DO UPDATE SET name = excluded.name, plan_json = excluded.plan_json, "
      "loaded_version = excluded.loaded_version",
      std::string_view(plan.name), std::string_view(text), update.state.version);
  write_objects(update);
  write_counters(update.state);
  tx.commit();
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
      reader_, "WHERE seq > ?1 AND (?2 IS NULL OR element = ?2 OR matched_element = ?2) ORDER BY seq LIMIT ?3",
      since_seq, element, static_cast<std::int64_t>(limit));
}

void Store::commit_scan(const ScanEntry& scan, const std::optional<ObservationEntry>& lines,
                        const std::optional<RequestRecord>& request) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(writer_);
  write_scan(scan, lines);
  if (request) write_request(*request);
  tx.commit();
}

void Store::commit_batch(const std::vector<BatchEntry>& entries) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(writer_);
  for (const auto& entry : entries) {
    if (entry.scan)
      write_scan(*entry.scan, entry.observation);
    else if (entry.observation)
      write_observation(*entry.observation);
    if (entry.request) write_request(*entry.request);
  }
  tx.commit();
}

void Store::write_scan(const ScanEntry& scan, const std::optional<ObservationEntry>& lines) {
  if (lines) write_observation(*lines);
  Statement s(writer_,
              "INSERT INTO scans(seq, observer, sensor, stamp, received_at, payload, lines_seq) "
              "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)");
  s.bind(1, scan.seq).bind(2, scan.observer).bind(3, scan.sensor).bind(4, scan.stamp_s).bind(5, now_unix_s());
  s.bind(6, scan.payload);
  if (lines)
    s.bind(7, lines->update.state.last_observation_seq);
  else
    s.bind_null(7);
  s.run();
}

void Store::commit_robot_pose(const RobotPoseEntry& pose) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(writer_);
  Statement s(writer_,
              "INSERT INTO robot_poses(robot, x, y, theta, cov, stamp, received_at, state) "
              "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
  bind_all(s, std::string_view(pose.robot), pose.x, pose.y, pose.theta);
  if (pose.cov)
    bind_matrix(s, 5, *pose.cov);
  else
    s.bind_null(5);
  s.bind(6, pose.stamp);
  s.bind(7, pose.received_at);
  s.bind(8, std::string_view(pose.state));
  s.run();
  tx.commit();
}

std::vector<Store::RobotJournal> Store::robot_journal(std::size_t track_points) {
  std::lock_guard lock(writer_mutex_);
  std::map<std::string, RobotJournal> robots;
  const auto robot = [&robots](const std::string& id) -> RobotJournal& {
    auto& r = robots[id];
    r.robot = id;
    return r;
  };
  const auto seen = [](RobotJournal& r, double first, double last) {
    r.first_seen = r.first_seen == 0 ? first : std::min(r.first_seen, first);
    r.last_seen = std::max(r.last_seen, last);
  };
  {
    Statement s(writer_,
                "SELECT observer, sensor, COUNT(*), MIN(received_at), MAX(received_at) FROM scans "
                "GROUP BY observer, sensor");
    while (s.step()) {
      auto& r = robot(s.column_text(0));
      r.scans[s.column_text(1)] = s.column_int(2);
      seen(r, s.column_double(3), s.column_double(4));
    }
  }
  {
    Statement s(writer_,
                "SELECT observer, COUNT(*), MIN(received_at), MAX(received_at) FROM observations "
                "WHERE kind = 'client' GROUP BY observer");
    while (s.step()) {
      auto& r = robot(s.column_text(0));
      r.primitives = s.column_int(1);
      seen(r, s.column_double(2), s.column_double(3));
    }
  }
  {
    Statement s(writer_, "SELECT robot, COUNT(*), MIN(received_at), MAX(received_at) FROM robot_poses GROUP BY robot");
    while (s.step()) {
      auto& r = robot(s.column_text(0));
      r.poses = s.column_int(1);
      seen(r, s.column_double(2), s.column_double(3));
    }
  }
  for (auto& [id, r] : robots) {
    if (!r.scans.empty()) {
      Statement s(writer_, "SELECT payload, received_at FROM scans WHERE observer = ?1 ORDER BY seq DESC LIMIT 1");
      s.bind(1, std::string_view(id));
      if (s.step()) {
        r.last_scan_payload = s.column_text(0);
        r.last_scan_received_at = s.column_double(1);
      }
    }
    Statement s(writer_,
                "SELECT x, y, theta, cov, stamp, received_at, state FROM robot_poses WHERE robot = ?1 "
                "ORDER BY seq DESC LIMIT ?2");
    s.bind(1, std::string_view(id));
    s.bind(2, static_cast<std::int64_t>(track_points));
    while (s.step()) {
      RobotPoseEntry pose{id,           s.column_double(0), s.column_double(1), s.column_double(2),
                          std::nullopt, s.column_double(4), s.column_double(5), s.column_text(6)};
      if (!s.column_doubles(3).empty()) pose.cov = read_matrix<Eigen::Matrix3d>(s, 3);
      r.poses_newest_first.push_back(std::move(pose));
    }
  }
  std::vector<RobotJournal> out;
  for (auto& [id, r] : robots) out.push_back(std::move(r));
  return out;
}

std::int64_t Store::last_scan_seq() {
  std::lock_guard lock(writer_mutex_);
  return query_int(writer_, "SELECT COALESCE(MAX(seq), 0) FROM scans");
}

bool Store::has_observation(const std::string& observer, const std::string& payload) {
  std::lock_guard lock(writer_mutex_);
  Statement s(writer_, "SELECT 1 FROM observations WHERE observer = ?1 AND payload = ?2 LIMIT 1");
  s.bind(1, std::string_view(observer));
  s.bind(2, std::string_view(payload));
  return s.step();
}

std::vector<Store::ScanRecord> Store::scans_after(std::int64_t after) {
  std::lock_guard lock(writer_mutex_);
  Statement s(writer_, "SELECT seq, payload FROM scans WHERE seq > ?1 ORDER BY seq");
  s.bind(1, after);
  std::vector<ScanRecord> result;
  while (s.step()) result.push_back({s.column_int(0), s.column_text(1)});
  return result;
}

namespace {

std::vector<float> read_floats(const Statement& s, int column, std::size_t expected) {
  const auto* data = static_cast<const float*>(s.column_blob(column));
  const auto bytes = s.column_bytes(column);
  if (bytes != expected * sizeof(float)) throw StorageError("corrupt grid tile in database");
  return std::vector<float>(data, data + expected);
}

void bind_floats(Statement& s, int index, const std::vector<float>& values) {
  s.bind_blob(index, values.data(), sizeof(float) * values.size());
}

}  // namespace

std::optional<Store::StoredGrid> Store::load_grid() {
  std::lock_guard lock(writer_mutex_);
  StoredGrid grid;
  {
    Statement s(writer_, "SELECT resolution, tile_size, through_scan_seq FROM grid_meta WHERE id = 1");
    if (!s.step()) return std::nullopt;
    grid.resolution_m = s.column_double(0);
    grid.tile_size_cells = s.column_int(1);
    grid.through_scan_seq = s.column_int(2);
  }
  const auto cells = static_cast<std::size_t>(grid.tile_size_cells * grid.tile_size_cells);
  Statement s(writer_, "SELECT tx, ty, log_odds, m_occupied, m_empty, conflict FROM grid_tiles ORDER BY tx, ty");
  while (s.step()) {
    fusion::OccupancyGrid::TileData data;
    data.log_odds = read_floats(s, 2, cells);
    data.m_occupied = read_floats(s, 3, cells);
    data.m_empty = read_floats(s, 4, cells);
    data.conflict = read_floats(s, 5, cells);
    grid.tiles.emplace_back(fusion::TileIndex{s.column_int(0), s.column_int(1)}, std::move(data));
  }
  return grid;
}

namespace {

std::vector<std::uint32_t> read_counts(const Statement& s, int column) {
  const auto bytes = static_cast<std::size_t>(s.column_bytes(column));
  if (bytes % sizeof(std::uint32_t) != 0) throw StorageError("corrupt edge beam counts in database");
  const auto* data = static_cast<const std::uint32_t*>(s.column_blob(column));
  return std::vector<std::uint32_t>(data, data + bytes / sizeof(std::uint32_t));
}

}  // namespace

std::vector<Store::StoredEdgeBeams> Store::load_edge_beams() {
  std::lock_guard lock(writer_mutex_);
  Statement s(writer_, "SELECT object, edge, x0, y0, x1, y1, through, ended FROM edge_beams ORDER BY object, edge");
  std::vector<StoredEdgeBeams> result;
  while (s.step()) {
    StoredEdgeBeams row;
    row.object_id = s.column_text(0);
    row.edge = s.column_int(1);
    row.beams.p0 = {s.column_double(2), s.column_double(3)};
    row.beams.p1 = {s.column_double(4), s.column_double(5)};
    row.beams.through = read_counts(s, 6);
    row.beams.ended = read_counts(s, 7);
    if (row.beams.through.size() != row.beams.ended.size() || row.edge < 0)
      throw StorageError("corrupt edge beam counts in database");
    result.push_back(std::move(row));
  }
  return result;
}

void Store::flush_grid(const StoredGrid& changed) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(writer_);
  run(writer_,
      "INSERT INTO grid_meta(id, resolution, tile_size, through_scan_seq) VALUES (1, ?1, ?2, ?3) "
      "ON CONFLICT(id) DO UPDATE SET resolution = excluded.resolution, tile_size = excluded.tile_size, "
      "through_scan_seq = excluded.through_scan_seq",
      changed.resolution_m, changed.tile_size_cells, changed.through_scan_seq);
  Statement s(writer_,
              "INSERT INTO grid_tiles(tx, ty, log_odds, m_occupied, m_empty, conflict) VALUES (?1, ?2, ?3, ?4, ?5, ?6) "
              "ON CONFLICT(tx, ty) DO UPDATE SET log_odds = excluded.log_odds, m_occupied = excluded.m_occupied, "
              "m_empty = excluded.m_empty, conflict = excluded.conflict");
  for (const auto& [index, data] : changed.tiles) {
    s.bind(1, index.x).bind(2, index.y);
    bind_floats(s, 3, data.log_odds);
    bind_floats(s, 4, data.m_occupied);
    bind_floats(s, 5, data.m_empty);
    bind_floats(s, 6, data.conflict);
    s.run();
  }
  Statement beams(writer_,
                  "INSERT INTO edge_beams(object, edge, x0, y0, x1, y1, through, ended) "
                  "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8) ON CONFLICT(object, edge) DO UPDATE SET x0 = excluded.x0, "
                  "y0 = excluded.y0, x1 = excluded.x1, y1 = excluded.y1, through = excluded.through, "
                  "ended = excluded.ended");
  for (const auto& row : changed.edge_beams) {
    beams.bind(1, std::string_view(row.object_id)).bind(2, row.edge);
    beams.bind(3, row.beams.p0.x()).bind(4, row.beams.p0.y()).bind(5, row.beams.p1.x()).bind(6, row.beams.p1.y());
    beams.bind_blob(7, row.beams.through.data(), sizeof(std::uint32_t) * row.beams.through.size());
    beams.bind_blob(8, row.beams.ended.data(), sizeof(std::uint32_t) * row.beams.ended.size());
    beams.run();
  }
  tx.commit();
}

std::vector<world::DecisionRecord> Store::observation_decisions(std::int64_t observation_seq) {
  std::lock_guard lock(reader_mutex_);
  return select_decisions(reader_, "WHERE observation_seq = ?1 ORDER BY seq", observation_seq);
}

std::int64_t Store::scans_missing_line_decisions() {
  std::lock_guard lock(reader_mutex_);
  return query_int(reader_,
                   "SELECT COUNT(*) FROM scans WHERE lines_seq IS NOT NULL AND NOT EXISTS "
                   "(SELECT 1 FROM decisions d WHERE d.observation_seq = scans.lines_seq)");
}

std::vector<world::DecisionRecord> Store::object_decisions(const std::string& object_id, std::size_t limit) {
  std::lock_guard lock(reader_mutex_);
  return select_decisions(reader_, "WHERE object = ?1 OR matched_object = ?1 ORDER BY seq LIMIT ?2",
                          std::string_view(object_id), static_cast<std::int64_t>(limit));
}

std::vector<world::DecisionRecord> Store::latest_decisions(std::size_t count) {
  std::lock_guard lock(reader_mutex_);
  auto result =
      select_decisions(reader_, "WHERE idx >= 0 ORDER BY seq DESC LIMIT ?1", static_cast<std::int64_t>(count));
  std::reverse(result.begin(), result.end());
  return result;
}

}  // namespace wm::storage
