#include "server/storage/store.h"

#include <string>

#include "server/storage/postgres.h"
#include "server/storage/sqlite.h"
#include "server/storage/store_internal.h"

// Opening the database and its schema: the migrations, one per version (SQLite), or one to the current version
// (PostgreSQL). The tables' reads and writes are in
// store_world.cpp, store_journal.cpp, store_plan.cpp and store_grid.cpp.
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
    // v10: a scan is journaled in its binary form (scan_record.h: what the grid takes, bit for bit), not as the
    // request body it came in; payload is '' for such rows. Rows stored before keep their JSON body (scan NULL),
    // which start-up still reads.
    R"sql(
ALTER TABLE scans ADD COLUMN scan BLOB;
)sql",
    // v11: an element seen from both sides (a thin surface; its facing is then NULL). Elements stored before read
    // as of unknown side, which the next view gives them.
    R"sql(
ALTER TABLE elements ADD COLUMN both_ways INTEGER NOT NULL DEFAULT 0;
)sql",
};
constexpr int kMigrationCount = static_cast<int>(sizeof(kMigrations) / sizeof(kMigrations[0]));
static_assert(kMigrationCount == Store::kSchemaVersion);

// PostgreSQL starts at the current version in one step: the same tables and columns as SQLite's eleven migrations,
// with PostgreSQL's types (BIGINT, DOUBLE PRECISION, BYTEA; identity columns where SQLite numbers rows itself), and
// each element's segment and each object's position as PostGIS geometry in the map's frame (metres, SRID 0), kept by
// the database from the stored numbers so that GIS tools read the live map. A later version appends one entry here
// and one to kMigrations.
struct PostgresMigration {
  int to_version;
  const char* sql;
};
constexpr PostgresMigration kPostgresMigrations[] = {
    {11, R"sql(
CREATE TABLE schema_version(version INTEGER NOT NULL);
CREATE TABLE meta(key TEXT PRIMARY KEY, value BIGINT NOT NULL);
CREATE TABLE floor_plan(id INTEGER PRIMARY KEY CHECK (id = 1), name TEXT NOT NULL, plan_json TEXT NOT NULL,
                        loaded_version BIGINT NOT NULL);
CREATE TABLE objects(ord BIGINT PRIMARY KEY, id TEXT NOT NULL UNIQUE, x DOUBLE PRECISION NOT NULL,
                     y DOUBLE PRECISION NOT NULL, theta DOUBLE PRECISION NOT NULL, pose_cov BYTEA NOT NULL,
                     confirmations BIGINT NOT NULL, adjustments BIGINT NOT NULL, updated_version BIGINT NOT NULL,
                     geom geometry(Point) GENERATED ALWAYS AS (ST_MakePoint(x, y)) STORED);
CREATE TABLE elements(number BIGINT PRIMARY KEY, rho DOUBLE PRECISION NOT NULL, phi DOUBLE PRECISION NOT NULL,
                      cov BYTEA NOT NULL, t0 DOUBLE PRECISION NOT NULL, t1 DOUBLE PRECISION NOT NULL,
                      support BIGINT NOT NULL, source TEXT NOT NULL, observer TEXT NOT NULL,
                      created_version BIGINT NOT NULL, updated_version BIGINT NOT NULL,
                      updated_at DOUBLE PRECISION NOT NULL DEFAULT 0, moments BYTEA, facing DOUBLE PRECISION,
                      both_ways BIGINT NOT NULL DEFAULT 0,
                      geom geometry(LineString) GENERATED ALWAYS AS (ST_MakeLine(
                        ST_MakePoint(rho * cos(phi) - t0 * sin(phi), rho * sin(phi) + t0 * cos(phi)),
                        ST_MakePoint(rho * cos(phi) - t1 * sin(phi), rho * sin(phi) + t1 * cos(phi)))) STORED);
CREATE INDEX elements_geom ON elements USING GIST(geom);
CREATE TABLE observations(seq BIGINT PRIMARY KEY, kind TEXT NOT NULL, observer TEXT NOT NULL,
                          stamp DOUBLE PRECISION NOT NULL, received_at DOUBLE PRECISION NOT NULL, payload TEXT NOT NULL);
CREATE TABLE decisions(seq BIGINT PRIMARY KEY, observation_seq BIGINT NOT NULL REFERENCES observations(seq),
                       idx BIGINT NOT NULL, action TEXT NOT NULL, rule TEXT NOT NULL, explanation TEXT NOT NULL,
                       element TEXT, object TEXT, mahalanobis_sq DOUBLE PRECISION, fallback BIGINT NOT NULL,
                       observer TEXT NOT NULL, p0x DOUBLE PRECISION NOT NULL, p0y DOUBLE PRECISION NOT NULL,
                       p1x DOUBLE PRECISION NOT NULL, p1y DOUBLE PRECISION NOT NULL,
                       origin TEXT NOT NULL DEFAULT 'client', sensor TEXT NOT NULL DEFAULT 'unknown',
                       matched_element TEXT, matched_object TEXT, observed BYTEA, before BYTEA, after BYTEA);
CREATE INDEX decisions_by_element ON decisions(element);
CREATE INDEX decisions_by_matched_element ON decisions(matched_element);
CREATE INDEX decisions_by_observation ON decisions(observation_seq);
CREATE TABLE scans(seq BIGINT PRIMARY KEY, observer TEXT NOT NULL, sensor TEXT NOT NULL, stamp DOUBLE PRECISION NOT NULL,
                   received_at DOUBLE PRECISION NOT NULL, payload TEXT NOT NULL, lines_seq BIGINT, scan BYTEA);
CREATE INDEX scans_by_observer ON scans(observer, seq);
CREATE TABLE grid_tiles(tx BIGINT NOT NULL, ty BIGINT NOT NULL, log_odds BYTEA NOT NULL, m_occupied BYTEA NOT NULL,
                        m_empty BYTEA NOT NULL, conflict BYTEA NOT NULL, PRIMARY KEY (tx, ty));
CREATE TABLE grid_meta(id INTEGER PRIMARY KEY CHECK (id = 1), resolution DOUBLE PRECISION NOT NULL,
                       tile_size BIGINT NOT NULL, through_scan_seq BIGINT NOT NULL);
CREATE TABLE requests(ord BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY, request_id TEXT NOT NULL UNIQUE,
                      kind TEXT NOT NULL, body_hash BIGINT NOT NULL, seq BIGINT NOT NULL, version BIGINT NOT NULL,
                      grid_revision BIGINT NOT NULL, lines_seq BIGINT, created_at DOUBLE PRECISION NOT NULL);
CREATE TABLE placements(ord BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY, x DOUBLE PRECISION NOT NULL,
                        y DOUBLE PRECISION NOT NULL, theta DOUBLE PRECISION NOT NULL, scale DOUBLE PRECISION NOT NULL,
                        cov BYTEA NOT NULL, rule TEXT NOT NULL, decision_seq BIGINT NOT NULL, version BIGINT NOT NULL,
                        created_at DOUBLE PRECISION NOT NULL);
CREATE TABLE georeference(id INTEGER PRIMARY KEY CHECK (id = 1), latitude DOUBLE PRECISION NOT NULL,
                          longitude DOUBLE PRECISION NOT NULL, heading DOUBLE PRECISION NOT NULL);
CREATE TABLE robot_poses(seq BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY, robot TEXT NOT NULL,
                         x DOUBLE PRECISION NOT NULL, y DOUBLE PRECISION NOT NULL, theta DOUBLE PRECISION NOT NULL,
                         cov BYTEA, stamp DOUBLE PRECISION NOT NULL, received_at DOUBLE PRECISION NOT NULL,
                         state TEXT NOT NULL);
CREATE INDEX robot_poses_by_robot ON robot_poses(robot, seq);
CREATE TABLE plan_changes(ord BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY, change_id TEXT NOT NULL,
                          verdict TEXT NOT NULL, plan_before TEXT, decision_seq BIGINT NOT NULL, version BIGINT NOT NULL,
                          created_at DOUBLE PRECISION NOT NULL);
CREATE TABLE edge_beams(object TEXT NOT NULL, edge BIGINT NOT NULL, x0 DOUBLE PRECISION NOT NULL,
                        y0 DOUBLE PRECISION NOT NULL, x1 DOUBLE PRECISION NOT NULL, y1 DOUBLE PRECISION NOT NULL,
                        through BYTEA NOT NULL, ended BYTEA NOT NULL, PRIMARY KEY(object, edge));
)sql"},
};

std::unique_ptr<Connection> open_connection(const StoreOptions& options, bool writer) {
  if (is_postgres_uri(options.path)) {
    auto connection = std::make_unique<PostgresConnection>(options.path, options.postgres_schema, writer);
    if (writer && options.fence) connection->set_fence(*options.fence);
    return connection;
  }
  if (options.fence) throw StorageError("a fence needs a PostgreSQL store");
  return std::make_unique<SqliteConnection>(options.path, writer);
}

// Where the store is, for messages: a file's path, or a PostgreSQL schema (never the URI: it may hold a password).
std::string describe(const StoreOptions& options) {
  return is_postgres_uri(options.path) ? "postgresql schema '" + options.postgres_schema + "'"
                                       : "database '" + options.path + "'";
}

}  // namespace

Store::Store(const StoreOptions& options) : options_(options), writer_(open_connection(options, true)) {
  if (writer_->dialect() == Dialect::sqlite) {
    writer_->exec("PRAGMA journal_mode=WAL");
    writer_->exec(options_.synchronous_full ? "PRAGMA synchronous=FULL" : "PRAGMA synchronous=NORMAL");
    writer_->exec("PRAGMA foreign_keys=ON");
  } else {
    // on: a commit returns once its WAL record is flushed to disk (as SQLite's FULL); off: after a crash of the
    // database server the last commits may be lost, never half of one (as NORMAL).
    writer_->exec(options_.synchronous_full ? "SET synchronous_commit TO on" : "SET synchronous_commit TO off");
  }
  migrate();
  reader_ = open_connection(options, false);
}

Dialect Store::dialect() const { return writer_->dialect(); }

int Store::schema_version() {
  std::lock_guard lock(writer_mutex_);
  return writer_->schema_version();
}

void Store::migrate() {
  const int found = schema_version();
  if (found > kSchemaVersion)
    throw StorageError(describe(options_) + " has schema version " + std::to_string(found) +
                       ", newer than this build's " + std::to_string(kSchemaVersion) + ": refusing to touch it");
  if (writer_->dialect() == Dialect::postgresql) {
    for (const auto& step : kPostgresMigrations) {
      if (step.to_version <= found) continue;
      Transaction tx(*writer_);
      writer_->exec(step.sql);
      writer_->set_schema_version(step.to_version);
      tx.commit();
    }
    return;
  }
  for (int v = found; v < kSchemaVersion; ++v) {
    Transaction tx(*writer_);
    writer_->exec(kMigrations[v]);
    writer_->set_schema_version(v + 1);
    tx.commit();
  }
}

}  // namespace wm::storage
