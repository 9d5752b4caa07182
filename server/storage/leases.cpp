#include "server/storage/leases.h"

#include "server/storage/postgres.h"

namespace wm::storage {

void ensure_lease_schema(Connection& connection) {
  // Under an advisory lock: nodes starting at once would otherwise race to make the same schema.
  connection.exec(R"sql(
BEGIN;
SELECT pg_advisory_xact_lock(7461001);
CREATE SCHEMA IF NOT EXISTS wm_cluster;
CREATE TABLE IF NOT EXISTS wm_cluster.leases(map TEXT PRIMARY KEY, node TEXT NOT NULL, epoch BIGINT NOT NULL,
                                             expires_at TIMESTAMPTZ NOT NULL);
CREATE OR REPLACE FUNCTION wm_cluster.fence(m TEXT, n TEXT, e BIGINT) RETURNS void AS $fence$
DECLARE
  held RECORD;
BEGIN
  -- FOR SHARE: a node taking the lease over waits until this transaction ends.
  SELECT node, epoch, expires_at INTO held FROM wm_cluster.leases WHERE map = m FOR SHARE;
  IF NOT FOUND OR held.node <> n OR held.epoch <> e OR held.expires_at <= clock_timestamp() THEN
    RAISE EXCEPTION 'fenced: map % is not held by node % at epoch % (lease: node %, epoch %, expires %)',
      m, n, e, held.node, held.epoch, held.expires_at USING ERRCODE = 'WM001';
  END IF;
END
$fence$ LANGUAGE plpgsql;
COMMIT;
)sql");
}

LeaseTable::LeaseTable(const std::string& uri)
    : connection_(std::make_unique<PostgresConnection>(uri, "public", false)) {
  ensure_lease_schema(*connection_);
}

std::optional<std::int64_t> LeaseTable::acquire(const std::string& map, const std::string& node,
                                                std::chrono::milliseconds ttl) {
  Statement s(*connection_,
              "INSERT INTO wm_cluster.leases(map, node, epoch, expires_at) "
              "VALUES (?1, ?2, 1, clock_timestamp() + ?3 * interval '1 millisecond') "
              "ON CONFLICT (map) DO UPDATE SET node = excluded.node, epoch = wm_cluster.leases.epoch + 1, "
              "expires_at = excluded.expires_at "
              "WHERE wm_cluster.leases.expires_at <= clock_timestamp() OR wm_cluster.leases.node = excluded.node "
              "RETURNING epoch");
  s.bind(1, std::string_view(map)).bind(2, std::string_view(node)).bind(3, static_cast<std::int64_t>(ttl.count()));
  if (!s.step()) return std::nullopt;
  return s.column_int(0);
}

bool LeaseTable::renew(const std::string& map, const std::string& node, std::int64_t epoch,
                       std::chrono::milliseconds ttl) {
  Statement s(*connection_,
              "UPDATE wm_cluster.leases SET expires_at = clock_timestamp() + ?4 * interval '1 millisecond' "
              "WHERE map = ?1 AND node = ?2 AND epoch = ?3 AND expires_at > clock_timestamp() RETURNING epoch");
  s.bind(1, std::string_view(map)).bind(2, std::string_view(node)).bind(3, epoch);
  s.bind(4, static_cast<std::int64_t>(ttl.count()));
  return s.step();
}

void LeaseTable::release(const std::string& map, const std::string& node, std::int64_t epoch) {
  Statement(*connection_,
            "UPDATE wm_cluster.leases SET expires_at = clock_timestamp() WHERE map = ?1 AND node = ?2 AND epoch = ?3")
      .bind(1, std::string_view(map))
      .bind(2, std::string_view(node))
      .bind(3, epoch)
      .run();
}

std::vector<Lease> LeaseTable::leases() {
  Statement s(*connection_,
              "SELECT map, node, epoch, EXTRACT(EPOCH FROM expires_at - clock_timestamp()) FROM wm_cluster.leases "
              "ORDER BY map");
  std::vector<Lease> result;
  while (s.step()) result.push_back({s.column_text(0), s.column_text(1), s.column_int(2), s.column_double(3)});
  return result;
}

}  // namespace wm::storage
