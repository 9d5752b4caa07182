#pragma once

#include <chrono>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rules/engine.h"
#include "server/api/drive_relay.h"
#include "server/api/router.h"
#include "server/foxglove/foxglove_options.h"
#include "server/http/http_server.h"
#include "server/service/world_service.h"
#include "server/shm/shared_map_export.h"
#include "server/storage/store.h"

namespace wm::config {

/// Bad command line or configuration: wmd prints it with the usage and exits with status 2.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Everything wmd is configured with, validated once at start-up.
struct ServerConfig {
  storage::StoreOptions store{"worldmodel.db", true};
  rules::EngineOptions rules;
  service::ServiceOptions service;
  api::ApiOptions api;
  http::HttpOptions http;
  shm::ShmOptions shm;
  foxglove::FoxgloveOptions foxglove;
  api::DriveOptions drive;                               // driving robots through wmd (--drive-*)
  std::optional<std::filesystem::path> floor_plan_file;  // loaded at start (demo), replacing the stored plan
  /// The maps besides the default one (the --db file), one SQLite file each; default: "<db>.maps" beside it.
  std::filesystem::path maps_dir;
  /// PostgreSQL store: this node's name on the maps' leases (default: host name and process id), and the leases'
  /// time to live (renewed every third of it; a node that stopped loses its maps after it).
  std::string node_id;
  std::chrono::milliseconds lease_ttl{3000};
  /// A node of a cluster (--cluster-id; PostgreSQL only): the cluster's name, the URL the other nodes reach this one
  /// at (--advertise; default http://<bind address or host name>:<port>), and the node-to-node token (from
  /// --cluster-token-file or WM_CLUSTER_TOKEN, never the command line). Empty cluster_id: no cluster.
  std::string cluster_id;
  std::string advertise_url;
  std::string cluster_token;
  bool help = false;
  bool print_network = false;
};

/// Parses wmd's arguments. Unknown flags, missing values and out-of-range numbers throw ConfigError.
ServerConfig parse_command_line(const std::vector<std::string>& args, const std::filesystem::path& default_rules_dir,
                                const std::filesystem::path& default_web_dir = {});

std::string usage();

}  // namespace wm::config
