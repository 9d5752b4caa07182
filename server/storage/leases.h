#pragma once

// Who owns a map when several wmd nodes share one PostgreSQL database: a lease per map, with a fencing epoch.
//
// A node takes a map's lease when it is free or expired (the epoch goes up by one: each owner has its own), renews
// it while it holds it, and gives it back when it stops. Every write transaction of the owner's store checks, in the
// same transaction, that the lease is still its own, at its epoch, and unexpired (wm_cluster.fence, which also holds
// the lease row against change until the commit): an owner that lost its lease (paused past it, cut off) commits
// nothing more, and a node taking the lease over waits for a commit already under way. Times are the database
// server's clock, so the nodes' clocks need not agree.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "server/storage/database.h"

namespace wm::storage {

/// A commit refused because the store's node no longer holds the map's lease at its epoch.
class FencedError : public StorageError {
 public:
  using StorageError::StorageError;
};

/// The lease a store's writes are fenced by (StoreOptions::fence).
struct Fence {
  std::string map;
  std::string node;
  std::int64_t epoch = 0;
  /// The lease's time to live. A fenced transaction holds the lease row until its commit, so a writer that stalls
  /// inside one (paused, cut off) would hold a takeover back: the database ends such a transaction after half of it
  /// (idle_in_transaction_session_timeout), and it commits nothing. 0: no limit.
  std::int64_t ttl_ms = 0;
};

struct Lease {
  std::string map;
  std::string node;
  std::int64_t epoch = 0;
  double expires_in_s = 0;  // negative: expired
};

/// A node of a cluster as the node table has it.
struct NodeRow {
  std::string cluster;
  std::string node;
  std::string url;             // where the other nodes forward its maps' requests
  double heartbeat_age_s = 0;  // since its last heartbeat, on the database's clock
  double up_s = 0;             // since it joined
};

/// The cluster's nodes (wm_cluster.nodes), each one's row kept fresh by its own heartbeat.
class NodeTable {
 public:
  /// @throw StorageError when the database cannot be reached or the table made.
  explicit NodeTable(const std::string& uri);
  /// Records that `node` of `cluster`, reached at `url`, is alive now (its row made or refreshed).
  void heartbeat(const std::string& cluster, const std::string& node, const std::string& url);
  /// Takes `node`'s row out (a clean stop).
  void leave(const std::string& node);
  /// The nodes of `cluster`, by id, the dead ones too (their heartbeat_age_s says so).
  std::vector<NodeRow> nodes(const std::string& cluster);

 private:
  std::unique_ptr<Connection> connection_;
};

/// The lease table (schema wm_cluster of the database), made when missing.
class LeaseTable {
 public:
  /// `lock_wait` > 0: acquire waits at most that long for a fenced transaction of the old owner that holds the lease
  /// row; when the lease has run out, that owner's fenced sessions are ended (their transaction commits nothing: a
  /// node paused inside one cannot hold a takeover back) and the lease taken. 0: acquire waits for the commit as
  /// long as it takes. @throw StorageError when the database cannot be reached or the table made.
  explicit LeaseTable(const std::string& uri, std::chrono::milliseconds lock_wait = std::chrono::milliseconds(0));

  /// Takes `map` for `node` for `ttl` when it is free, expired or already `node`'s; the new epoch, or nullopt when
  /// another node holds it. Taking over an expired lease waits for a commit its old owner has under way.
  std::optional<std::int64_t> acquire(const std::string& map, const std::string& node, std::chrono::milliseconds ttl);
  /// Extends `node`'s lease at `epoch` by `ttl` from now; false when it is no longer held so (lost).
  bool renew(const std::string& map, const std::string& node, std::int64_t epoch, std::chrono::milliseconds ttl);
  /// Gives the lease back (it expires now), when `node` holds it at `epoch`.
  void release(const std::string& map, const std::string& node, std::int64_t epoch);
  /// Every lease, by map.
  std::vector<Lease> leases();

 private:
  std::optional<std::int64_t> acquire_once(const std::string& map, const std::string& node,
                                           std::chrono::milliseconds ttl);
  std::unique_ptr<Connection> connection_;
  const std::chrono::milliseconds lock_wait_;
};

/// The name a fenced store's sessions carry (application_name), by which a node taking an expired lease over ends the
/// ones that still hold it.
std::string fence_session_name(const std::string& map, std::int64_t epoch);

/// The leases one node holds, renewed every third of their time to live by a thread of its own. A lease that cannot
/// be renewed is lost (the map's store is fenced from then on) and reported to `on_lost`. Thread-safe.
class LeaseKeeper {
 public:
  /// @throw StorageError when the database cannot be reached.
  LeaseKeeper(const std::string& uri, std::string node, std::chrono::milliseconds ttl,
              std::function<void(const std::string& map, const std::string& why)> on_lost);
  /// Gives every lease back.
  ~LeaseKeeper();
  LeaseKeeper(const LeaseKeeper&) = delete;
  LeaseKeeper& operator=(const LeaseKeeper&) = delete;

  /// Takes `map`'s lease: the fence its store writes under. A lease held by another node is waited for once, at most
  /// its time to live (a node that stopped leaves it to run out). @throw StorageError naming the node that holds it.
  Fence take(const std::string& map);
  /// Takes `map`'s lease when it is free or expired now, without waiting; nullopt when another node holds it.
  std::optional<Fence> try_take(const std::string& map);
  /// The maps whose leases this node holds now.
  std::vector<std::string> held();
  /// Gives `map`'s lease back (nothing when not held).
  void give_back(const std::string& map);
  const std::string& node() const { return node_; }

 private:
  void renew_loop();

  const std::string node_;
  const std::chrono::milliseconds ttl_;
  const std::function<void(const std::string&, const std::string&)> on_lost_;
  // Renewals have a connection of their own: a takeover that waits for a row lock never delays them.
  LeaseTable renew_table_;  // the renewer's thread only (and the destructor, after it ended)
  std::mutex take_mutex_;   // take_table_
  LeaseTable take_table_;
  std::mutex mutex_;                          // held_, stopping_
  std::map<std::string, std::int64_t> held_;  // map -> epoch
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread renewer_;
};

/// Makes the lease table and the fence function when missing (idempotent; LeaseTable and a fenced store call it).
void ensure_lease_schema(Connection& connection);

}  // namespace wm::storage
