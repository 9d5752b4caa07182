#include "server/service/map_registry.h"

#include <algorithm>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "server/service/service_errors.h"
#include "server/storage/postgres.h"

namespace wm::service {
namespace {

constexpr std::string_view kMapSuffix = ".db";
constexpr std::string_view kRemovedPrefix = ".removed-";
// A map's schema when the maps are in PostgreSQL: map_<id>.
constexpr std::string_view kMapSchemaPrefix = "map_";

std::filesystem::path map_file(const std::filesystem::path& data_dir, const std::string& id) {
  return data_dir / (id + std::string(kMapSuffix));
}

// The database file and the two SQLite keeps beside it in WAL mode.
std::vector<std::filesystem::path> sqlite_files(const std::filesystem::path& db) {
  return {db, db.string() + "-wal", db.string() + "-shm"};
}

// Where a removed map's file waits for its last holder: renamed with the removal's prefix, in the same directory.
std::filesystem::path removed_file(const std::filesystem::path& data_dir, const std::string& removed_as,
                                   const std::filesystem::path& file) {
  return data_dir / (removed_as + file.filename().string());
}

bool in_postgres(const MapRegistryOptions& options) { return storage::is_postgres_uri(options.store.path); }

// The maps in the data directory: its files <id>.db, sorted. What an interrupted removal left is removed.
std::vector<std::string> sqlite_maps(const MapRegistryOptions& options, common::Diagnostics& diagnostics) {
  std::vector<std::string> found;
  if (!std::filesystem::exists(options.data_dir)) return found;
  for (const auto& entry : std::filesystem::directory_iterator(options.data_dir)) {
    const auto name = entry.path().filename().string();
    if (name.starts_with(kRemovedPrefix)) {
      std::error_code ignored;
      std::filesystem::remove(entry.path(), ignored);  // a removal interrupted after its rename
      continue;
    }
    if (!entry.is_regular_file() || !name.ends_with(kMapSuffix)) continue;
    const auto id = name.substr(0, name.size() - kMapSuffix.size());
    if (id == kDefaultMapId)
      diagnostics.report(common::Severity::warning, "maps",
                         "'" + entry.path().string() + "' not opened: the default map is the --db file");
    else if (valid_map_id(id))
      found.push_back(id);
  }
  std::sort(found.begin(), found.end());
  return found;
}

struct StoredMap {
  std::string id;
  bool removed = false;  // marked by a removal that has not dropped it yet
};

// The maps in a PostgreSQL database: its schemas named map_<id>, by id, each with its removal mark. A schema whose
// store has not made its meta table yet (a map being created) counts as a map.
std::vector<StoredMap> postgres_map_schemas(const std::string& uri) {
  storage::PostgresConnection catalog(uri, "public", false);
  std::vector<StoredMap> found;
  storage::Statement s(catalog,
                       "SELECT n.nspname, CAST(to_regclass(quote_ident(n.nspname) || '.meta') IS NOT NULL AS INTEGER) "
                       "FROM pg_namespace n WHERE starts_with(n.nspname, ?1) ORDER BY n.nspname");
  s.bind(1, kMapSchemaPrefix);
  while (s.step()) {
    const auto schema = s.column_text(0);
    const auto id = schema.substr(kMapSchemaPrefix.size());
    if (!valid_map_id(id) || id == kDefaultMapId) continue;
    found.push_back({id, false});
    if (s.column_int(1) == 0) continue;
    storage::Statement removed(catalog,
                               "SELECT 1 FROM " + storage::quoted_schema(schema) + ".meta WHERE key = 'removed'");
    found.back().removed = removed.step();
  }
  return found;
}

// The maps in a PostgreSQL database. One a removal marked (and a crash kept from going) is dropped now.
std::vector<std::string> postgres_maps(const MapRegistryOptions& options, common::Diagnostics& diagnostics) {
  std::vector<std::string> found;
  for (const auto& map : postgres_map_schemas(options.store.path)) {
    if (!map.removed) {
      found.push_back(map.id);
      continue;
    }
    storage::PostgresConnection(options.store.path, "public", false)
        .exec("DROP SCHEMA " + storage::quoted_schema(std::string(kMapSchemaPrefix) + map.id) + " CASCADE");
    diagnostics.report(common::Severity::info, "maps", "map '" + map.id + "', removed before a restart, dropped");
  }
  return found;
}

// Drops a removed map's schema, after its store closed. A failure leaves the mark, and the next start drops it.
void drop_postgres_map(const storage::StoreOptions& store, const std::string& id) {
  try {
    storage::PostgresConnection(store.path, "public", false)
        .exec("DROP SCHEMA " + storage::quoted_schema(std::string(kMapSchemaPrefix) + id) + " CASCADE");
  } catch (const storage::StorageError&) {
    // The schema keeps its removal mark: the next start drops it.
  }
}

}  // namespace

std::filesystem::path map_rules_dir(const std::filesystem::path& rules_dir, std::string_view map_id) {
  return rules_dir / "maps" / std::string(map_id);
}

std::string map_schema_name(std::string_view id) { return std::string(kMapSchemaPrefix) + std::string(id); }

std::optional<std::string> map_id_of_schema(std::string_view schema) {
  if (!schema.starts_with(kMapSchemaPrefix)) return std::nullopt;
  auto id = std::string(schema.substr(kMapSchemaPrefix.size()));
  if (!valid_map_id(id) || id == kDefaultMapId) return std::nullopt;
  return id;
}

bool valid_map_id(std::string_view id) {
  if (id.empty() || id.size() > 32) return false;
  const auto allowed = [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-'; };
  return std::all_of(id.begin(), id.end(), allowed) && id.front() != '_' && id.front() != '-';
}

MapInstance::MapInstance(std::string map_id, const MapRegistryOptions& options, std::string knowledge_base,
                         common::Diagnostics& diagnostics)
    : id(std::move(map_id)),
      store([&] {
        auto store_options = options.store;
        if (in_postgres(options)) {
          store_options.postgres_schema = map_schema_name(id);
          if (options.leases && options.cluster) {
            store_options.fence = options.leases->try_take(store_options.postgres_schema);
            if (!store_options.fence) throw storage::StorageError("map '" + id + "' is held by another node");
          } else if (options.leases) {
            store_options.fence = options.leases->take(store_options.postgres_schema);
          }
        } else
          store_options.path = map_file(options.data_dir, id).string();
        return store_options;
      }()),
      engine([&] {
        auto rules_options = options.rules;
        rules_options.knowledge_base = std::move(knowledge_base);
        rules_options.map_rules_dir = map_rules_dir(options.rules.rules_dir, id);
        return rules_options;
      }()),
      world(options.service, store, engine, diagnostics, &events) {}

MapInstance::~MapInstance() = default;

MapRegistry::MapRegistry(MapRegistryOptions options, common::Diagnostics& diagnostics)
    : options_(std::move(options)), diagnostics_(diagnostics) {
  if (options_.cluster) return;  // the cluster gives this node its maps (adopt)
  const auto found =
      in_postgres(options_) ? postgres_maps(options_, diagnostics_) : sqlite_maps(options_, diagnostics_);
  std::lock_guard lock(mutex_);
  for (const auto& id : found) {
    try {
      maps_.emplace(id, open(id));
    } catch (const std::exception& e) {
      // One map that does not open (a damaged file) leaves the others serving; its data stays for a person to look at.
      diagnostics_.report(common::Severity::error, "maps", "map '" + id + "' not opened: " + e.what());
    }
  }
}

std::shared_ptr<MapInstance> MapRegistry::open(const std::string& id) {
  const auto knowledge_base = "wm_kb_map" + std::to_string(++knowledge_bases_);
  // The last holder of a removed map takes its files with it, after the store has closed them. The registry may be
  // gone by then: the deleter keeps what it needs.
  return std::shared_ptr<MapInstance>(
      new MapInstance(id, options_, knowledge_base, diagnostics_),
      [data_dir = options_.data_dir, store = options_.store, leases = options_.leases](MapInstance* map) {
        const auto removed_as = map->removed_as;
        const auto id = map->id;
        delete map;
        if (removed_as.empty()) return;
        if (storage::is_postgres_uri(store.path)) {
          drop_postgres_map(store, id);
          if (leases) leases->give_back(map_schema_name(id));
          return;
        }
        for (const auto& file : sqlite_files(map_file(data_dir, id))) {
          std::error_code ignored;
          std::filesystem::remove(removed_file(data_dir, removed_as, file), ignored);
        }
      });
}

std::vector<std::string> MapRegistry::ids() const {
  std::lock_guard lock(mutex_);
  std::vector<std::string> ids;
  for (const auto& [id, map] : maps_) ids.push_back(id);
  return ids;
}

std::shared_ptr<MapInstance> MapRegistry::find(const std::string& id) const {
  std::lock_guard lock(mutex_);
  const auto found = maps_.find(id);
  return found == maps_.end() ? nullptr : found->second;
}

std::shared_ptr<MapInstance> MapRegistry::create(const std::string& id) {
  if (!valid_map_id(id)) throw std::invalid_argument("map id '" + id + "': " + std::string(kMapIdRule));
  if (id == kDefaultMapId) throw Conflict("the default map always exists");
  std::lock_guard lock(mutex_);
  if (maps_.count(id)) throw Conflict("map '" + id + "' exists");
  if (options_.cluster)
    for (const auto& map : postgres_map_schemas(options_.store.path))
      if (map.id == id) throw Conflict("map '" + id + "' exists (on another node of the cluster)");
  std::filesystem::create_directories(options_.data_dir);
  auto map = open(id);
  maps_.emplace(id, map);
  return map;
}

void MapRegistry::remove(const std::string& id) {
  std::shared_ptr<MapInstance> map;
  std::string removed_as;
  {
    std::lock_guard lock(mutex_);
    const auto found = maps_.find(id);
    if (found == maps_.end()) throw NotFound("no map '" + id + "'");
    map = std::move(found->second);
    maps_.erase(found);
    removed_as = std::string(kRemovedPrefix) + std::to_string(++removals_) + "-";
  }
  if (in_postgres(options_)) {
    // Marked at once (a start drops a marked schema); a request that still holds the map ends against it, and the
    // schema is dropped when the last one lets go.
    map->store.mark_removed();
    map->removed_as = removed_as;
    map->events.publish(events::EventKind::map_removed, R"({"type":"map_removed","map":")" + id + "\"}");
    return;
  }
  // Renamed aside at once: the map is gone from the directory whatever happens next (a start removes what a crash
  // left). A request that still holds the map ends against it, into the renamed files: it came before the removal.
  for (const auto& file : sqlite_files(map_file(options_.data_dir, id))) {
    std::error_code missing;  // -wal and -shm may not exist
    std::filesystem::rename(file, removed_file(options_.data_dir, removed_as, file), missing);
  }
  map->removed_as = removed_as;
  // Those who follow the map's events learn why nothing more comes.
  map->events.publish(events::EventKind::map_removed, R"({"type":"map_removed","map":")" + id + "\"}");
}

std::vector<std::string> MapRegistry::stored_ids() const {
  if (!in_postgres(options_)) return ids();
  std::vector<std::string> found;
  for (const auto& map : postgres_map_schemas(options_.store.path))
    if (!map.removed) found.push_back(map.id);
  return found;
}

bool MapRegistry::adopt(const std::string& id) {
  if (!valid_map_id(id) || id == kDefaultMapId) return false;
  std::lock_guard lock(mutex_);
  if (maps_.count(id)) return true;
  maps_.emplace(id, open(id));
  return true;
}

void MapRegistry::let_go(const std::string& id, const std::string& owner_url) {
  std::shared_ptr<MapInstance> map;
  {
    std::lock_guard lock(mutex_);
    const auto found = maps_.find(id);
    if (found == maps_.end()) return;
    map = std::move(found->second);
    maps_.erase(found);
  }
  map->events.publish(events::EventKind::map_moved,
                      nlohmann::json{{"type", "map_moved"}, {"map", id}, {"owner", owner_url}}.dump());
  if (on_let_go_) on_let_go_(map.get());
}

int MapRegistry::sweep_removed() {
  if (!in_postgres(options_) || !options_.leases) return 0;
  int dropped = 0;
  for (const auto& map : postgres_map_schemas(options_.store.path)) {
    if (!map.removed || find(map.id)) continue;
    const auto schema = map_schema_name(map.id);
    if (!options_.leases->try_take(schema)) continue;  // its holder is alive and drops it itself
    drop_postgres_map(options_.store, map.id);
    options_.leases->give_back(schema);
    diagnostics_.report(common::Severity::info, "maps",
                        "map '" + map.id + "', removed by a node that stopped, dropped");
    ++dropped;
  }
  return dropped;
}

}  // namespace wm::service
