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
#include <cstdint>
#include <optional>
#include <string>
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
};

struct Lease {
  std::string map;
  std::string node;
  std::int64_t epoch = 0;
  double expires_in_s = 0;  // negative: expired
};

/// The lease table (schema wm_cluster of the database), made when missing.
class LeaseTable {
 public:
  /// @throw StorageError when the database cannot be reached or the table made.
  explicit LeaseTable(const std::string& uri);

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
  std::unique_ptr<Connection> connection_;
};

/// Makes the lease table and the fence function when missing (idempotent; LeaseTable and a fenced store call it).
void ensure_lease_schema(Connection& connection);

}  // namespace wm::storage
