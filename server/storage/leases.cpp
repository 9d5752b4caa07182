#include "server/storage/leases.h"

#include <algorithm>
#include <cmath>

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
CREATE TABLE IF NOT EXISTS wm_cluster.nodes(node TEXT PRIMARY KEY, cluster TEXT NOT NULL, url TEXT NOT NULL,
                                            joined_at TIMESTAMPTZ NOT NULL, heartbeat_at TIMESTAMPTZ NOT NULL);
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

NodeTable::NodeTable(const std::string& uri) : connection_(std::make_unique<PostgresConnection>(uri, "public", false)) {
  ensure_lease_schema(*connection_);
}

void NodeTable::heartbeat(const std::string& cluster, const std::string& node, const std::string& url) {
  Statement(
      *connection_,
      "INSERT INTO wm_cluster.nodes(node, cluster, url, joined_at, heartbeat_at) "
      "VALUES (?1, ?2, ?3, clock_timestamp(), clock_timestamp()) "
      "ON CONFLICT (node) DO UPDATE SET heartbeat_at = clock_timestamp(), url = excluded.url, "
      "cluster = excluded.cluster, joined_at = CASE WHEN wm_cluster.nodes.url = excluded.url "
      "AND wm_cluster.nodes.cluster = excluded.cluster THEN wm_cluster.nodes.joined_at ELSE clock_timestamp() END")
      .bind(1, std::string_view(node))
      .bind(2, std::string_view(cluster))
      .bind(3, std::string_view(url))
      .run();
}

void NodeTable::leave(const std::string& node) {
  Statement(*connection_, "DELETE FROM wm_cluster.nodes WHERE node = ?1").bind(1, std::string_view(node)).run();
}

std::vector<NodeRow> NodeTable::nodes(const std::string& cluster) {
  Statement s(
      *connection_,
      "SELECT cluster, node, url, EXTRACT(EPOCH FROM clock_timestamp() - heartbeat_at), "
      "EXTRACT(EPOCH FROM clock_timestamp() - joined_at) FROM wm_cluster.nodes WHERE cluster = ?1 ORDER BY node");
  s.bind(1, std::string_view(cluster));
  std::vector<NodeRow> result;
  while (s.step())
    result.push_back({s.column_text(0), s.column_text(1), s.column_text(2), s.column_double(3), s.column_double(4)});
  return result;
}

std::string fence_session_name(const std::string& map, std::int64_t epoch) {
  return ("wm-fence/" + map + "/" + std::to_string(epoch)).substr(0, 63);
}

LeaseTable::LeaseTable(const std::string& uri, std::chrono::milliseconds lock_wait)
    : connection_(std::make_unique<PostgresConnection>(uri, "public", false)), lock_wait_(lock_wait) {
  ensure_lease_schema(*connection_);
  if (lock_wait_.count() > 0) connection_->exec("SET lock_timeout = " + std::to_string(lock_wait_.count()));
}

std::optional<std::int64_t> LeaseTable::acquire(const std::string& map, const std::string& node,
                                                std::chrono::milliseconds ttl) {
  try {
    return acquire_once(map, node, ttl);
  } catch (const StorageError&) {
    if (lock_wait_.count() <= 0) throw;
    // Waited lock_wait for the lease row: a fenced transaction holds it. Its lease ran out, so it can never commit;
    // its owner stalls inside it (paused, cut off). Its sessions are ended, which releases the row.
    std::optional<std::int64_t> expired;
    {
      Statement s(*connection_,
                  "SELECT epoch FROM wm_cluster.leases WHERE map = ?1 AND expires_at <= clock_timestamp()");
      s.bind(1, std::string_view(map));
      if (s.step()) expired = s.column_int(0);
    }
    if (!expired) throw;
    Statement end(*connection_,
                  "SELECT pg_terminate_backend(pid, 2000) FROM pg_stat_activity WHERE application_name = ?1 "
                  "AND pid <> pg_backend_pid()");
    end.bind(1, std::string_view(fence_session_name(map, *expired)));
    while (end.step()) {
    }
    return acquire_once(map, node, ttl);
  }
}

std::optional<std::int64_t> LeaseTable::acquire_once(const std::string& map, const std::string& node,
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

LeaseKeeper::LeaseKeeper(const std::string& uri, std::string node, std::chrono::milliseconds ttl,
                         std::function<void(const std::string& map, const std::string& why)> on_lost)
    : node_(std::move(node)),
      ttl_(ttl),
      on_lost_(std::move(on_lost)),
      renew_table_(uri),
      take_table_(uri, std::max(ttl / 10, std::chrono::milliseconds(50))) {
  renewer_ = std::thread([this] { renew_loop(); });
}

LeaseKeeper::~LeaseKeeper() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  renewer_.join();
  std::lock_guard take(take_mutex_);
  for (const auto& [map, epoch] : held_) {
    try {
      take_table_.release(map, node_, epoch);
    } catch (const StorageError&) {
      // It expires by itself.
    }
  }
}

Fence LeaseKeeper::take(const std::string& map) {
  std::unique_lock take(take_mutex_);
  auto epoch = take_table_.acquire(map, node_, ttl_);
  if (!epoch) {
    // A node that stopped (a crash, a restart of this one) leaves its lease to run out: wait for that once, at most
    // one lease time. A node alive renews it meanwhile, and the map stays its own.
    double left_s = 0;
    for (const auto& lease : take_table_.leases())
      if (lease.map == map) left_s = lease.expires_in_s;
    if (left_s > 0 && left_s <= std::chrono::duration<double>(ttl_).count()) {
      {
        std::unique_lock lock(mutex_);
        wake_.wait_for(lock, std::chrono::duration<double>(left_s + 0.05), [this] { return stopping_; });
      }
      epoch = take_table_.acquire(map, node_, ttl_);
    }
  }
  if (!epoch) {
    std::string holder = "another node";
    for (const auto& lease : take_table_.leases())
      if (lease.map == map)
        holder = "node '" + lease.node + "' (epoch " + std::to_string(lease.epoch) + ") for another " +
                 std::to_string(static_cast<int>(std::ceil(lease.expires_in_s))) + " s";
    throw StorageError("map '" + map + "' is held by " + holder + ": one node writes a map at a time");
  }
  std::lock_guard lock(mutex_);
  held_[map] = *epoch;
  return Fence{map, node_, *epoch, ttl_.count()};
}

std::optional<Fence> LeaseKeeper::try_take(const std::string& map) {
  std::optional<std::int64_t> epoch;
  {
    std::lock_guard take(take_mutex_);
    epoch = take_table_.acquire(map, node_, ttl_);
  }
  if (!epoch) return std::nullopt;
  std::lock_guard lock(mutex_);
  held_[map] = *epoch;
  return Fence{map, node_, *epoch, ttl_.count()};
}

std::vector<std::string> LeaseKeeper::held() {
  std::lock_guard lock(mutex_);
  std::vector<std::string> maps;
  for (const auto& [map, epoch] : held_) maps.push_back(map);
  return maps;
}

void LeaseKeeper::give_back(const std::string& map) {
  std::int64_t epoch = 0;
  {
    std::lock_guard lock(mutex_);
    const auto found = held_.find(map);
    if (found == held_.end()) return;
    epoch = found->second;
    held_.erase(found);
  }
  std::lock_guard take(take_mutex_);
  try {
    take_table_.release(map, node_, epoch);
  } catch (const StorageError&) {
    // It expires by itself.
  }
}

void LeaseKeeper::renew_loop() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    wake_.wait_for(lock, ttl_ / 3, [this] { return stopping_; });
    if (stopping_) break;
    const auto held = held_;
    lock.unlock();
    std::vector<std::string> lost;
    for (const auto& [map, epoch] : held) {
      try {
        if (!renew_table_.renew(map, node_, epoch, ttl_)) lost.push_back(map);
      } catch (const StorageError&) {
        // The database did not answer: tried again next time, while the lease still runs (the fence refuses the
        // map's commits once it has run out).
      }
    }
    lock.lock();
    for (const auto& map : lost) {
      // Unless it was given back or taken again meanwhile.
      const auto found = held_.find(map);
      if (found == held_.end() || found->second != held.at(map)) continue;
      held_.erase(found);
      lock.unlock();
      if (on_lost_) on_lost_(map, "its lease ran out or another node took it over");
      lock.lock();
    }
  }
}

}  // namespace wm::storage
