#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/diagnostics.h"
#include "rules/engine.h"
#include "server/events/event_hub.h"
#include "server/service/world_service.h"
#include "server/storage/store.h"

namespace wm::service {

/// The map a server always has: its routes are today's (/api/v1/scans, ...) and its store the one wmd was started
/// with (--db); the registry holds the others, and never one of this id.
inline constexpr std::string_view kDefaultMapId = "default";

/// What valid_map_id accepts, as refusals say it.
inline constexpr std::string_view kMapIdRule =
    "a map id is 1-32 of a-z, 0-9, '_' and '-', not starting with '_' or '-'";

/// A map's own rule files, loaded with the shared ones (rules::EngineOptions::map_rules_dir):
/// `<rules_dir>/maps/<id>`.
std::filesystem::path map_rules_dir(const std::filesystem::path& rules_dir, std::string_view map_id);

/// The PostgreSQL schema of map `id` (and the name of its lease): map_<id>.
std::string map_schema_name(std::string_view id);
/// The map id of a schema map_schema_name made; nullopt for any other schema (a node's default map).
std::optional<std::string> map_id_of_schema(std::string_view schema);

/// Whether `id` may name a map: 1–32 of [a-z0-9_-], starting with a letter or a digit (it goes into URLs and file
/// names as it is).
bool valid_map_id(std::string_view id);

struct MapRegistryOptions {
  /// One SQLite file per map, `<id>.db` (with its -wal and -shm); created when missing.
  std::filesystem::path data_dir;
  storage::StoreOptions store;  // the path is the map's own
  rules::EngineOptions rules;   // the rules directory is shared; the knowledge base is the map's own
  ServiceOptions service;
  /// PostgreSQL store: each map's store writes under its lease, taken when the map opens (nullptr: SQLite).
  storage::LeaseKeeper* leases = nullptr;
  /// A node of a cluster (PostgreSQL): no map is opened at start, a map is opened by adopt() when the cluster gives
  /// it to this node, and its lease is taken without waiting (another node's live lease: not opened).
  bool cluster = false;
};

/// One map: its store, its knowledge base and its world service, built in that order and gone in the reverse.
struct MapInstance {
  MapInstance(std::string id, const MapRegistryOptions& options, std::string knowledge_base,
              common::Diagnostics& diagnostics);
  ~MapInstance();
  MapInstance(const MapInstance&) = delete;
  MapInstance& operator=(const MapInstance&) = delete;

  const std::string id;
  storage::Store store;
  rules::Engine engine;
  events::EventHub events;  // the map's live events (/api/v1/maps/{map}/events)
  WorldService world;
  /// Set by MapRegistry::remove: the prefix its files were renamed with, to go when the last user lets go.
  std::string removed_as;
};

/// The maps of one server, each with its own store file, knowledge base, grids and writer, so that no map waits on
/// another's commits. A map is found by its id; a request holds it (a shared pointer) while it runs, so a map removed
/// meanwhile stays whole until that request ends and only then takes its files with it. Thread-safe.
class MapRegistry {
 public:
  /// Opens every map whose file is in options.data_dir and removes what an interrupted removal left; a map that does
  /// not open is reported to `diagnostics` and left out. The directory is made by the first create().
  /// @throw std::filesystem::filesystem_error when the directory cannot be read.
  MapRegistry(MapRegistryOptions options, common::Diagnostics& diagnostics);
  MapRegistry(const MapRegistry&) = delete;
  MapRegistry& operator=(const MapRegistry&) = delete;

  /// The ids of the maps, sorted.
  std::vector<std::string> ids() const;
  /// The map `id`, or nullptr when there is none.
  std::shared_ptr<MapInstance> find(const std::string& id) const;
  /// A new, empty map. @throw std::invalid_argument for an id valid_map_id refuses; Conflict when it exists or is
  /// kDefaultMapId; std::filesystem::filesystem_error when the directory cannot be made.
  std::shared_ptr<MapInstance> create(const std::string& id);
  /// Removes map `id`: it is found no more at once, and its files are renamed aside so that a crash leaves no map
  /// behind (the next start removes them); they go when the last request that holds the map ends (such a request
  /// came before the removal and ends as it would have). @throw NotFound.
  void remove(const std::string& id);

  /// Every map the store holds, open here or not, sorted (a cluster's maps; on SQLite the open ones). Removed maps are
  /// not listed. @throw storage::StorageError when the database does not answer.
  std::vector<std::string> stored_ids() const;
  /// Opens map `id` here (a cluster gave it to this node); true when it is open here now. @throw
  /// storage::StorageError when its lease is another node's or it does not open.
  bool adopt(const std::string& id);
  /// Closes map `id` here: it moved to another node (`owner_url`, empty when not known yet). Who follows its events is
  /// told (map_moved) and then the stream ends; a request that holds it ends against it, and its store refuses to
  /// commit once the lease is another's. Nothing when it is not open here.
  void let_go(const std::string& id, const std::string& owner_url);
  /// Drops the maps a removal marked whose holder died before it could drop them (their leases are free), each under
  /// its lease. Returns how many. PostgreSQL only.
  int sweep_removed();
  /// Called with each map let_go closes, before the registry lets go of it (what holds a map besides the registry,
  /// such as its shared-memory export, lets go too). Set before the maps are served.
  void on_let_go(std::function<void(const MapInstance*)> closed) { on_let_go_ = std::move(closed); }

 private:
  std::shared_ptr<MapInstance> open(const std::string& id);

  const MapRegistryOptions options_;
  common::Diagnostics& diagnostics_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<MapInstance>> maps_;
  std::int64_t knowledge_bases_ = 0;  // the next map's knowledge base is wm_kb_map<n>
  std::int64_t removals_ = 0;         // removed files are named .removed-<n>-<file>
  std::function<void(const MapInstance*)> on_let_go_;
};

}  // namespace wm::service
