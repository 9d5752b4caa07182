#include "server/service/cluster_member.h"

#include <algorithm>
#include <cmath>

#include "server/storage/postgres.h"

namespace wm::service {
namespace {

double seconds(std::chrono::milliseconds ms) { return std::chrono::duration<double>(ms).count(); }

}  // namespace

ClusterMember::ClusterMember(ClusterOptions options, MapRegistry& registry, storage::LeaseKeeper& leases,
                             common::Diagnostics& diagnostics)
    : options_(std::move(options)),
      registry_(registry),
      leases_(leases),
      diagnostics_(diagnostics),
      nodes_(options_.store_uri),
      query_(std::make_unique<storage::PostgresConnection>(options_.store_uri, "public", false)) {}

ClusterMember::~ClusterMember() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (loop_.joinable()) loop_.join();
  try {
    nodes_.leave(options_.node_id);
  } catch (const storage::StorageError&) {
    // Its heartbeat stops: the others count it dead after one lease time.
  }
}

void ClusterMember::start(const std::string& url) {
  {
    std::lock_guard lock(mutex_);
    url_ = url;
  }
  round();
  loop_ = std::thread([this] { run(); });
}

std::string ClusterMember::url() const {
  std::lock_guard lock(mutex_);
  return url_;
}

void ClusterMember::lease_lost(const std::string& schema) {
  const auto id = map_id_of_schema(schema);
  if (!id) return;  // the node's default map: its store refuses to commit, and wmd reports it
  {
    std::lock_guard lock(mutex_);
    lost_.insert(*id);
  }
  wake_.notify_all();
}

void ClusterMember::run() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    wake_.wait_for(lock, options_.lease_ttl / 6, [this] { return stopping_ || !lost_.empty(); });
    if (stopping_) break;
    lock.unlock();
    try {
      round();
    } catch (const std::exception& e) {
      // The database did not answer: the next round tries again (the leases run on, or run out and are lost).
      diagnostics_.report(common::Severity::warning, "cluster", std::string("a round failed: ") + e.what());
    }
    lock.lock();
  }
}

void ClusterMember::round() {
  const std::string url = this->url();
  nodes_.heartbeat(options_.cluster_id, options_.node_id, url);

  // Maps whose lease went elsewhere (or ran out) are closed first: their store refuses to commit anyway.
  std::set<std::string> lost;
  {
    std::lock_guard lock(mutex_);
    lost.swap(lost_);
  }
  // The open maps first, then the leases: a map opened in between (a create) has its lease already.
  const auto open = registry_.ids();
  const auto held = leases_.held();
  const std::set<std::string> held_set(held.begin(), held.end());
  for (const auto& id : open)
    if (!held_set.count(map_schema_name(id))) lost.insert(id);
  for (const auto& id : lost) {
    if (!registry_.find(id)) continue;
    std::string owner_url;
    try {
      if (const auto owner = owner_of(id); owner && owner->node != options_.node_id) owner_url = owner->url;
    } catch (const storage::StorageError&) {
      // Not known: the clients ask any node again.
    }
    registry_.let_go(id, owner_url);
    leases_.give_back(map_schema_name(id));  // when still held here: the map is closed, another node takes it
    {
      std::lock_guard lock(mutex_);
      ++lost_count_;
    }
    diagnostics_.report(common::Severity::warning, "cluster",
                        "map '" + id + "' lost its lease here" + (owner_url.empty() ? "" : ", now at " + owner_url));
  }

  // The maps no live lease holds, taken up to this node's share.
  const auto status = this->status();
  const auto alive = std::max<std::size_t>(
      1, std::count_if(status.nodes.begin(), status.nodes.end(), [](const ClusterNode& n) { return n.alive; }));
  std::size_t maps = status.unowned.size();
  for (const auto& lease : status.leases)
    if (lease.expires_in_s > 0) ++maps;
  const auto share = static_cast<std::size_t>(std::ceil(static_cast<double>(maps) / static_cast<double>(alive)));
  std::set<std::string> waited;
  {
    std::lock_guard lock(mutex_);
    waited.swap(waited_);
  }
  std::set<std::string> still_waiting;
  for (const auto& id : status.unowned) {
    if (registry_.ids().size() >= share && !waited.count(id)) {
      still_waiting.insert(id);
      continue;
    }
    try {
      if (registry_.adopt(id)) {
        std::lock_guard lock(mutex_);
        ++taken_;
        diagnostics_.report(common::Severity::info, "cluster", "took map '" + id + "' over");
      }
    } catch (const std::exception& e) {
      // Another node was quicker (its lease), or the map does not open here: the next round looks again.
      still_waiting.insert(id);
    }
  }
  {
    std::lock_guard lock(mutex_);
    waited_ = std::move(still_waiting);
  }
  // More maps here than the share while a live node has fewer: one is handed over per round (closed here and its
  // lease given back; a node under its share takes it at its next round, and clients meanwhile are told to ask
  // again). So maps made on one node, or left by a dead one, spread over the nodes, a new node included.
  const auto mine = registry_.ids();
  const bool someone_under = std::any_of(status.nodes.begin(), status.nodes.end(), [&](const ClusterNode& node) {
    return node.alive && node.node != options_.node_id && node.maps.size() < share;
  });
  if (mine.size() > share && someone_under) {
    const auto& id = mine.back();
    registry_.let_go(id, "");
    leases_.give_back(map_schema_name(id));
    std::lock_guard lock(mutex_);
    ++handed_over_;
  }
  registry_.sweep_removed();
}

std::optional<MapOwner> ClusterMember::owner_of(const std::string& id) {
  std::lock_guard lock(query_mutex_);
  storage::Statement s(*query_,
                       "SELECT l.node, COALESCE(n.url, '') FROM wm_cluster.leases l LEFT JOIN wm_cluster.nodes n "
                       "ON n.node = l.node WHERE l.map = ?1 AND l.expires_at > clock_timestamp()");
  s.bind(1, std::string_view(map_schema_name(id)));
  if (!s.step()) return std::nullopt;
  return MapOwner{s.column_text(0), s.column_text(1)};
}

bool ClusterMember::has_map(const std::string& id) {
  const auto stored = registry_.stored_ids();
  return std::binary_search(stored.begin(), stored.end(), id);
}

ClusterStatus ClusterMember::status() {
  ClusterStatus status;
  status.cluster_id = options_.cluster_id;
  status.node_id = options_.node_id;
  const auto stored = registry_.stored_ids();
  const double ttl_s = seconds(options_.lease_ttl);
  std::set<std::string> owned;
  {
    std::lock_guard lock(query_mutex_);
    storage::Statement nodes(*query_,
                             "SELECT node, url, EXTRACT(EPOCH FROM clock_timestamp() - heartbeat_at), "
                             "EXTRACT(EPOCH FROM clock_timestamp() - joined_at) FROM wm_cluster.nodes "
                             "WHERE cluster = ?1 ORDER BY node");
    nodes.bind(1, std::string_view(options_.cluster_id));
    while (nodes.step()) {
      ClusterNode node;
      node.node = nodes.column_text(0);
      node.url = nodes.column_text(1);
      node.heartbeat_age_s = nodes.column_double(2);
      node.up_s = nodes.column_double(3);
      // A live node heartbeats every sixth of a lease time: one silent for two thirds of it is counted out, so
      // that when a dead node's leases run out the others' shares already include its maps.
      node.alive = node.heartbeat_age_s < ttl_s * 2 / 3;
      status.nodes.push_back(std::move(node));
    }
    storage::Statement leases(*query_,
                              "SELECT map, node, epoch, EXTRACT(EPOCH FROM expires_at - clock_timestamp()) "
                              "FROM wm_cluster.leases ORDER BY map");
    while (leases.step()) {
      const auto id = map_id_of_schema(leases.column_text(0));
      if (!id || !std::binary_search(stored.begin(), stored.end(), *id)) continue;
      status.leases.push_back({*id, leases.column_text(1), leases.column_int(2), leases.column_double(3)});
    }
  }
  for (const auto& lease : status.leases) {
    if (lease.expires_in_s <= 0) continue;
    owned.insert(lease.map);
    for (auto& node : status.nodes)
      if (node.node == lease.node) node.maps.push_back(lease.map);
  }
  for (const auto& id : stored)
    if (!owned.count(id)) status.unowned.push_back(id);
  std::lock_guard lock(mutex_);
  status.taken = taken_;
  status.lost = lost_count_;
  status.handed_over = handed_over_;
  return status;
}

}  // namespace wm::service
