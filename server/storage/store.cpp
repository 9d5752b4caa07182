#include "server/storage/store.h"

#include <string>

#include "server/storage/store_internal.h"

// Opening the file and its schema: the migrations, one per version. The tables' reads and writes are in
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

}  // namespace

using internal::query_int;

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

}  // namespace wm::storage
