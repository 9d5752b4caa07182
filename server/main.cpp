// wmd: the world-model server. Builds the object graph (store → knowledge base → world service → HTTP)
// and passes references down; nothing global.
#include <pthread.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio/ip/address.hpp>
#include <csignal>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <thread>

#include "apriori/floor_plan.h"
#include "common/diagnostics.h"
#include "server/api/drive_relay.h"
#include "server/api/router.h"
#include "server/config/server_config.h"
#include "server/foxglove/bridge.h"
#include "server/foxglove/map_bridges.h"
#include "server/http/forward_client.h"
#include "server/http/http_server.h"
#include "server/service/cluster_member.h"
#include "server/service/map_registry.h"
#include "server/service/world_service.h"
#include "server/shm/shared_map_export.h"
#include "server/storage/postgres.h"
#include "server/storage/store.h"

#ifndef WM_DEFAULT_WEB_DIR
#define WM_DEFAULT_WEB_DIR "clients/web"
#endif
#ifndef WM_DEFAULT_RULES_DIR
#define WM_DEFAULT_RULES_DIR "rules/prolog"
#endif

namespace {

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read '" + path.string() + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

int main(int argc, char** argv) {
  using namespace wm;
  // Signals are taken by one thread with sigwait; every other thread (Asio, Prolog, writer) inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  config::ServerConfig cfg;
  try {
    cfg = config::parse_command_line(std::vector<std::string>(argv + 1, argv + argc), WM_DEFAULT_RULES_DIR,
                                     WM_DEFAULT_WEB_DIR);
  } catch (const config::ConfigError& e) {
    std::cerr << "wmd: " << e.what() << "\n" << config::usage();
    return 2;
  }
  if (cfg.help) {
    std::cout << config::usage();
    return 0;
  }
  if (cfg.print_network) {
    std::cout << service::default_network_yaml();
    return 0;
  }
  // What the parts below report as they run: echoed to stderr as before, and counted in GET /api/v1/health.
  common::Diagnostics diagnostics("wmd: ");
  try {
    // On PostgreSQL every map is written under its lease (one node writes a map at a time); the keeper outlives the
    // stores, and gives the leases back at a clean stop.
    std::unique_ptr<storage::LeaseKeeper> leases;
    // A node of a cluster closes a map whose lease it lost (set while the member lives).
    std::atomic<service::ClusterMember*> cluster_member = nullptr;
    const bool in_cluster = !cfg.cluster_id.empty();
    if (storage::is_postgres_uri(cfg.store.path)) {
      leases = std::make_unique<storage::LeaseKeeper>(
          cfg.store.path, cfg.node_id, cfg.lease_ttl,
          [&diagnostics, &cluster_member](const std::string& map, const std::string& why) {
            diagnostics.report(common::Severity::error, "leases",
                               "lost the lease of map schema '" + map + "': " + why + "; its writes are refused");
            if (auto* member = cluster_member.load()) member->lease_lost(map);
          });
      cfg.store.fence = leases->take(cfg.store.postgres_schema);
    }
    storage::Store store(cfg.store);
    auto default_rules = cfg.rules;
    default_rules.map_rules_dir = service::map_rules_dir(cfg.rules.rules_dir, service::kDefaultMapId);
    rules::Engine engine(default_rules);
    events::EventHub events;
    service::WorldService world(cfg.service, store, engine, diagnostics, &events);
    if (cfg.floor_plan_file) {
      auto plan = apriori::parse_floor_plan_json(read_file(*cfg.floor_plan_file), cfg.api.plan_limits);
      std::cout << "wmd: loaded floor plan '" << plan.name << "' (" << plan.objects.size() << " objects) from "
                << cfg.floor_plan_file->string() << "\n";
      world.load_floor_plan(std::move(plan));
    }
    // The other maps, each with its own store, knowledge base and writer (GET /api/v1/maps).
    auto map_store = cfg.store;
    map_store.fence.reset();  // each map has its own lease
    service::MapRegistry maps({cfg.maps_dir, map_store, cfg.rules, cfg.service, leases.get(), in_cluster}, diagnostics);
    // A cluster's node: takes maps over as nodes die (after the registry, which it fills; gone before it).
    std::optional<service::ClusterMember> cluster;
    std::optional<api::ClusterRouting> routing;
    if (in_cluster) {
      cluster.emplace(service::ClusterOptions{cfg.cluster_id, cfg.node_id, cfg.store.path, cfg.lease_ttl}, maps,
                      *leases, diagnostics);
      // A request passed on waits for its answer while its node keeps the map's lease, and at most this long.
      const auto forward_timeout = std::chrono::milliseconds(60'000);
      routing.emplace(api::ClusterRouting{
          &*cluster, cfg.cluster_token,
          [forward_timeout](const api::Request& request, const std::string& url,
                            const std::function<bool()>& still_worth_it) -> std::optional<api::Response> {
            try {
              return http::forward_request(request, url, forward_timeout, still_worth_it);
            } catch (const http::ForwardError&) {
              return std::nullopt;
            }
          }});
    }
    api::Services services{cfg.api, world};
    services.diagnostics = &diagnostics;
    services.maps = &maps;
    if (routing) services.cluster = &*routing;
    // The other maps' shared-memory exports, each made when its map is first used (after `maps`: gone before it).
    std::optional<api::MapExports> map_exports;
    if (cfg.shm.enabled) services.map_exports = &map_exports.emplace(cfg.shm, diagnostics);
    // A map that moved to another node keeps no export here.
    maps.on_let_go([&map_exports](const service::MapInstance* map) {
      if (map_exports) map_exports->forget(map);
    });
    // Before the HTTP server, which hands it to handlers, and after the world it reads.
    std::optional<shm::SharedMapExport> shared_memory;
    if (cfg.shm.enabled) {
      shared_memory.emplace(world, cfg.shm, services.map_cache->instance(), diagnostics, &events);
      services.shm = &*shared_memory;
      const auto status = shared_memory->status();
      if (status.available)
        std::cout << "wmd: shared memory /dev/shm/" << status.name << " (GET /api/v1/shm)\n";
      else
        diagnostics.report(common::Severity::warning, "shm", "warning: no shared memory export: " + status.error);
    }
    // Before the HTTP server, whose connections it serves, and after the world and the event hub it reads.
    foxglove::Bridge foxglove_bridge(
        cfg.foxglove, world, events, diagnostics,
        {"wmd (worldmodel)",
         services.map_cache->instance(),
         {{"api", "/api/v1"}, {"map_frame", "map"}, {"robot_frames", "<robot id>/base_link"}}});
    // The other maps' Foxglove clients (/foxglove?map=ID): a bridge per map while it has clients.
    foxglove::MapBridges map_bridges(
        cfg.foxglove, maps, diagnostics,
        {"wmd (worldmodel)", {}, {{"map_frame", "map"}, {"robot_frames", "<robot id>/base_link"}}},
        [&services](const std::shared_ptr<service::MapInstance>& map) {
          return services.map_caches->of(map)->instance();
        });
    // Before the HTTP server, whose drive connections it relays.
    api::DriveRelay drive_relay(cfg.drive);
    services.drive = &drive_relay;
    http::HttpServer::Handlers handlers{
        [&services](const api::Request& r) { return api::handle_request(r, services); },
        [](const api::Request& r) { return api::handler_lane(r); },
        [](const api::Request& r) { return api::is_websocket_upgrade(r); },
        [&services](const api::Request& r) { return api::authorize_events(r, services); },
        [&services](const api::Request& r) { return api::answer_at_once(r, services); },
        [&foxglove_bridge, &map_bridges,
         &drive_relay](const api::Request& r) -> std::shared_ptr<http::WebSocketEndpoint> {
          if (auto drive = drive_relay.connect(r)) return drive;
          // The route table names the subprotocol each WebSocket speaks; none is the events stream.
          if (api::websocket_subprotocol(r) != foxglove::kSubprotocol) return nullptr;
          if (const auto map = api::foxglove_map(r)) return map_bridges.connect(*map);
          return foxglove_bridge.connect();
        },
        [&services](const api::Request& r) { return api::map_events_hub(r, services); },
        [&services](const api::Request& r) { return api::map_events_elsewhere(r, services); }};
    http::HttpServer server(cfg.http, std::move(handlers), diagnostics, &events);
    if (cluster) {
      // Joins once it can be reached: the first round takes maps nobody serves.
      auto url = cfg.advertise_url;
      if (url.empty()) {
        const auto bind = boost::asio::ip::make_address(cfg.http.bind_address);
        std::string host = bind.is_v6() ? "[" + bind.to_string() + "]" : bind.to_string();
        if (bind.is_unspecified()) {
          char name[256] = {};
          ::gethostname(name, sizeof name - 1);
          host = name;
        }
        url = "http://" + host + ":" + std::to_string(server.port());
      }
      while (!url.empty() && url.back() == '/') url.pop_back();
      cluster_member = &*cluster;
      cluster->start(url);
      std::cout << "wmd: cluster " << cfg.cluster_id << ", node " << cfg.node_id << " at " << url << " serves "
                << maps.ids().size() << " of " << maps.stored_ids().size() << " map(s)\n";
    }
    std::thread signal_waiter([&server, signals] {
      int signal = 0;
      sigwait(&signals, &signal);
      server.stop();
    });
    if (cfg.api.token.empty() && !boost::asio::ip::make_address(cfg.http.bind_address).is_loopback())
      std::cerr << "wmd: warning: no --token and --bind " << cfg.http.bind_address
                << " (--insecure-no-token): anyone who reaches the port can change the map\n";
    const auto other_maps = maps.ids();
    const bool postgres = storage::is_postgres_uri(cfg.store.path);
    std::cout << "wmd: database "
              << (postgres ? "postgresql schema " + cfg.store.postgres_schema + " (node " + cfg.node_id + ", epoch " +
                                 std::to_string(cfg.store.fence->epoch) + ")"
                           : cfg.store.path)
              << ", rules " << cfg.rules.rules_dir.string() << "\n"
              << "wmd: " << other_maps.size() << " other map(s) in "
              << (postgres ? std::string("postgresql schemas map_<id>") : cfg.maps_dir.string()) << "\n"
              << "wmd: listening on http://" << cfg.http.bind_address << ":" << server.port() << "/" << std::endl;
    server.run();
    pthread_kill(signal_waiter.native_handle(), SIGTERM);  // wakes the waiter when run() ended otherwise
    signal_waiter.join();
    cluster_member = nullptr;
    cluster.reset();  // leaves the cluster: stops taking maps over
    std::cout << "wmd: stopped" << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "wmd: " << e.what() << std::endl;
    return 1;
  }
}
