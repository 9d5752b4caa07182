#include "tools/replay/log_replay.h"

#include <algorithm>
#include <chrono>

#include "common/diagnostics.h"
#include "logs/carmen_log_reader.h"
#include "logs/scan_body.h"
#include "rules/engine.h"
#include "server/storage/store.h"

namespace wm::replay {

LogReplayResult replay_log(const std::filesystem::path& log, const LogReplayOptions& options,
                           const std::function<void(service::WorldService&)>& on_service) {
  storage::StoreOptions store_options;
  store_options.path = (options.work_dir / "replay.db").string();
  store_options.synchronous_full = false;  // a replay can be run again; durability is tested elsewhere
  storage::Store store(store_options);
  rules::EngineOptions engine_options;
  engine_options.rules_dir = options.rules_dir;
  rules::Engine engine(engine_options);
  common::Diagnostics diagnostics("wmd: ");  // on stderr as wmd has them; nobody asks for the counts
  service::WorldService world(options.service, store, engine, diagnostics);

  if (options.plan) world.load_floor_plan(*options.plan);

  LogReplayResult result;
  logs::CarmenLogReader reader(log);
  const std::string observer = log.stem().stem().string();
  const Eigen::Matrix3d pose_cov =
      Eigen::Vector3d(options.sigma_xy_m * options.sigma_xy_m, options.sigma_xy_m * options.sigma_xy_m,
                      options.sigma_theta_rad * options.sigma_theta_rad)
          .asDiagonal();
  const auto start = std::chrono::steady_clock::now();
  std::size_t index = 0;
  while (auto scan = reader.next()) {
    if (index++ % std::max<std::size_t>(1, options.every) != 0) continue;
    world::ScanObservation request;
    request.observer = observer;
    request.stamp_s = scan->timestamp_s;
    request.pose_cov = pose_cov;
    // The request body as a client would post it: the journal keeps it to rebuild the grid at start.
    auto payload = logs::laser_scan_body(scan->scan, observer, scan->timestamp_s).dump();
    request.scan = std::move(scan->scan);
    world.post_scan(std::move(request), std::move(payload), std::nullopt);
    if (++result.scans == options.max_scans) break;
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.quality = service::measure_map_quality(world, world);
  if (on_service) on_service(world);
  return result;
}

}  // namespace wm::replay
