#include "server/service/map_recovery.h"

#include <string>

namespace wm::service {

bool journal_has_sonar(const std::vector<storage::Store::RobotJournal>& robots) {
  for (const auto& robot : robots)
    if (robot.scans.contains("sonar")) return true;
  return false;
}

void replay_journal_into_grid(storage::Store& store, GridStore& grid, const world::WorldState& map,
                              bool journal_has_sonar) {
  // The laser-only and sonar-only grids are not stored: a map that has seen sonar rebuilds them from the journal
  // through the last flush (the fused grid has those scans in its tiles), then takes the rest as every grid does.
  if (journal_has_sonar) {
    grid.start_side_grids();
    const auto through = grid.flushed_scan_seq();
    for_each_journaled_scan(store, 0, [&](std::int64_t seq, storage::JournaledScan&& record) {
      if (seq <= through) grid.insert_side_only(journaled_scan(std::move(record)));
    });
  }
  // A scan is journaled (with its line decisions) before it touches the grid, and the tiles are flushed later.
  for_each_journaled_scan(store, grid.flushed_scan_seq(), [&](std::int64_t seq, storage::JournaledScan&& record) {
    grid.insert(journaled_scan(std::move(record)), seq, map);
  });
  if (grid.last_scan_seq() != store.last_scan_seq())
    throw storage::StorageError("the scan journal ends at " + std::to_string(store.last_scan_seq()) +
                                " but the grid was rebuilt to " + std::to_string(grid.last_scan_seq()));
}

void restore_robots(std::vector<storage::Store::RobotJournal> journals, RobotRegistry& robots) {
  for (auto& journal : journals) {
    RobotState robot;
    robot.id = journal.robot;
    robot.scans = std::move(journal.scans);
    robot.primitives = journal.primitives;
    robot.poses = journal.poses;
    robot.first_seen_unix_s = journal.first_seen;
    robot.last_seen_unix_s = journal.last_seen;
    std::optional<RobotPose> from_scan;
    if (journal.last_scan) {
      try {
        from_scan = scan_pose(journaled_scan(std::move(*journal.last_scan)), journal.last_scan_received_at);
      } catch (const std::exception&) {
        // A payload this build no longer reads: the robot comes back without its scan pose.
      }
    }
    for (auto it = journal.poses_newest_first.rbegin(); it != journal.poses_newest_first.rend(); ++it)
      robot.track.push_back(RobotPose{it->x, it->y, it->theta, it->cov, it->stamp, it->received_at, "reported"});
    const auto* reported = robot.track.empty() ? nullptr : &robot.track.back();
    if (reported && (!from_scan || reported->received_at_unix_s >= from_scan->received_at_unix_s)) {
      robot.pose = *reported;
      robot.stopped = journal.poses_newest_first.front().state == "stopped";
    } else {
      robot.pose = from_scan;
    }
    robots.restore(std::move(robot));
  }
}

}  // namespace wm::service
