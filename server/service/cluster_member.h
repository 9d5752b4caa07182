#pragma once

// One wmd node of a cluster: several nodes share one PostgreSQL database, and each map is served by exactly one of
// them at a time, the holder of its lease (storage/leases.h). This node keeps its row in the node table fresh
// (a heartbeat), and every sixth of a lease time takes the maps no live lease holds: a dead node's, whose leases ran
// out, a removed node's, a new map's whose creator died. It takes them up to its share (the maps over the live
// nodes, rounded up); a map still without an owner one round later is taken whatever the share. A node over its
// share while another is under it hands one map over per round (maps made on one node spread; a new node gets its
// part). A map whose lease this node lost (paused, cut off) is closed here at once. Nothing here answers HTTP: the
// router asks owner_of and forwards.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "common/diagnostics.h"
#include "server/service/map_registry.h"
#include "server/storage/leases.h"

namespace wm::service {

struct ClusterOptions {
  std::string cluster_id;  // the nodes of one cluster share it
  std::string node_id;     // the lease holder's name, unique in the cluster
  std::string store_uri;   // postgresql://…
  std::chrono::milliseconds lease_ttl{3000};
};

/// A node of the cluster and the maps it serves, as the database says now.
struct ClusterNode {
  std::string node;
  std::string url;
  double heartbeat_age_s = 0;
  double up_s = 0;
  bool alive = false;  // heartbeat within two thirds of a lease time
  std::vector<std::string> maps;
};

/// A map's lease, as the database says now.
struct ClusterLease {
  std::string map;  // the map's id
  std::string node;
  std::int64_t epoch = 0;
  double expires_in_s = 0;  // negative: expired, the map waits for a node to take it
};

struct ClusterStatus {
  std::string cluster_id;
  std::string node_id;  // this node
  std::vector<ClusterNode> nodes;
  std::vector<ClusterLease> leases;
  std::vector<std::string> unowned;  // maps no live lease holds
  std::int64_t taken = 0;            // maps this node took over since it started
  std::int64_t lost = 0;             // maps this node lost (its lease ran out or was taken)
  std::int64_t handed_over = 0;      // maps this node gave to others to even the load
};

/// Where a map is served: the node holding its lease and the URL it gave.
struct MapOwner {
  std::string node;
  std::string url;
};

/// Thread-safe.
class ClusterMember {
 public:
  /// `registry` and `leases` must outlive this (they are wmd's, made before it). @throw storage::StorageError when
  /// the database cannot be reached.
  ClusterMember(ClusterOptions options, MapRegistry& registry, storage::LeaseKeeper& leases,
                common::Diagnostics& diagnostics);
  /// Stops the loop and takes this node's row out (its leases are given back by the keeper).
  ~ClusterMember();
  ClusterMember(const ClusterMember&) = delete;
  ClusterMember& operator=(const ClusterMember&) = delete;

  /// Joins the cluster as reachable at `url` (once the HTTP server listens): the first heartbeat and round run
  /// before this returns, then every sixth of a lease time on a thread of its own.
  void start(const std::string& url);
  /// The keeper lost the lease of a map's schema: the map is closed at the next round, which comes at once.
  void lease_lost(const std::string& schema);

  /// The node serving map `id` now (a live lease; this node too), fresh from the database; nullopt when none does
  /// (a takeover under way) or there is no such map. @throw storage::StorageError when the database does not answer.
  std::optional<MapOwner> owner_of(const std::string& id);
  /// Whether the cluster's store holds a map `id` (open on some node or waiting for one).
  bool has_map(const std::string& id);
  ClusterStatus status();
  const ClusterOptions& options() const { return options_; }
  /// This node's URL (empty before start).
  std::string url() const;

 private:
  void run();
  void round();

  const ClusterOptions options_;
  MapRegistry& registry_;
  storage::LeaseKeeper& leases_;
  common::Diagnostics& diagnostics_;
  storage::NodeTable nodes_;  // the loop's connection
  mutable std::mutex mutex_;  // below
  std::string url_;
  std::set<std::string> lost_;    // map ids whose leases were lost, to be closed
  std::set<std::string> waited_;  // unowned at the last round and not taken then
  std::int64_t taken_ = 0, lost_count_ = 0, handed_over_ = 0;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread loop_;
  std::mutex query_mutex_;                      // query_
  std::unique_ptr<storage::Connection> query_;  // owner_of, status: the request threads' connection
};

}  // namespace wm::service
