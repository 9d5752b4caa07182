#include <algorithm>
#include <map>
#include <string>

#include "server/storage/scan_record.h"
#include "server/storage/store.h"
#include "server/storage/store_internal.h"

// The journals: scans, request ids, reported robot poses, and what they say at start.
namespace wm::storage {

using internal::bind_all;
using internal::bind_matrix;
using internal::now_unix_s;
using internal::query_int;
using internal::read_matrix;
using internal::run;

namespace {

// A journal row (seq, observer, stamp, scan, payload) as start-up reads it. @throw StorageError for a damaged scan.
JournaledScan journaled_scan(const Statement& s) {
  JournaledScan record;
  record.seq = s.column_int(0);
  if (s.column_bytes(3) > 0) {
    try {
      record.scan = decode_scan(std::string_view(static_cast<const char*>(s.column_blob(3)), s.column_bytes(3)),
                                s.column_text(1), s.column_double(2));
    } catch (const StorageError& e) {
      throw StorageError("scan " + std::to_string(record.seq) + " of the journal is damaged: " + e.what());
    }
  } else {
    record.legacy_json = s.column_text(4);
  }
  return record;
}

}  // namespace

void Store::write_request(const RequestRecord& r) {
  run(*writer_,
      "INSERT INTO requests(request_id, kind, body_hash, seq, version, grid_revision, lines_seq, created_at) "
      "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
      std::string_view(r.request_id), std::string_view(r.kind), r.body_hash, r.seq, r.version, r.grid_revision,
      r.lines_seq, now_unix_s());
  // Bounded by count: rows are numbered in insertion order, so the oldest go in one range delete.
  run(*writer_, "DELETE FROM requests WHERE ord <= (SELECT MAX(ord) FROM requests) - ?1", options_.request_ids_kept);
}

std::optional<RequestRecord> Store::find_request(const std::string& request_id) {
  std::lock_guard lock(writer_mutex_);
  Statement s(*writer_,
              "SELECT kind, body_hash, seq, version, grid_revision, lines_seq FROM requests WHERE request_id = ?1");
  s.bind(1, std::string_view(request_id));
  if (!s.step()) return std::nullopt;
  RequestRecord r;
  r.request_id = request_id;
  r.kind = s.column_text(0);
  r.body_hash = s.column_int(1);
  r.seq = s.column_int(2);
  r.version = s.column_int(3);
  r.grid_revision = s.column_int(4);
  r.lines_seq = s.column_optional_int(5);
  return r;
}

void Store::commit_scan(const ScanEntry& scan, const std::optional<ObservationEntry>& lines,
                        const std::optional<RequestRecord>& request) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  write_scan(scan, lines);
  if (request) write_request(*request);
  tx.commit();
}

void Store::commit_batch(const std::vector<BatchEntry>& entries) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  for (const auto& entry : entries) {
    if (entry.scan)
      write_scan(*entry.scan, entry.observation);
    else if (entry.observation)
      write_observation(*entry.observation);
    if (entry.request) write_request(*entry.request);
  }
  tx.commit();
}

void Store::write_scan(const ScanEntry& scan, const std::optional<ObservationEntry>& lines) {
  if (lines) write_observation(*lines);
  Statement s(*writer_,
              "INSERT INTO scans(seq, observer, sensor, stamp, received_at, payload, lines_seq, scan) "
              "VALUES (?1, ?2, ?3, ?4, ?5, '', ?6, ?7)");
  const auto& observation = *scan.scan;
  const auto blob = encode_scan(observation);
  s.bind(1, scan.seq).bind(2, std::string_view(observation.observer)).bind(3, std::string_view(observation.sensor()));
  s.bind(4, observation.stamp_s).bind(5, now_unix_s());
  s.bind_blob(7, blob.data(), blob.size());
  if (lines)
    s.bind(6, lines->update.state.last_observation_seq);
  else
    s.bind_null(6);
  s.run();
}

void Store::commit_robot_pose(const RobotPoseEntry& pose) {
  std::lock_guard lock(writer_mutex_);
  Transaction tx(*writer_);
  Statement s(*writer_,
              "INSERT INTO robot_poses(robot, x, y, theta, cov, stamp, received_at, state) "
              "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
  bind_all(s, std::string_view(pose.robot), pose.x, pose.y, pose.theta);
  if (pose.cov)
    bind_matrix(s, 5, *pose.cov);
  else
    s.bind_null(5);
  s.bind(6, pose.stamp);
  s.bind(7, pose.received_at);
  s.bind(8, std::string_view(pose.state));
  s.run();
  tx.commit();
}

std::vector<Store::RobotJournal> Store::robot_journal(std::size_t track_points) {
  std::lock_guard lock(writer_mutex_);
  std::map<std::string, RobotJournal> robots;
  const auto robot = [&robots](const std::string& id) -> RobotJournal& {
    auto& r = robots[id];
    r.robot = id;
    return r;
  };
  const auto seen = [](RobotJournal& r, double first, double last) {
    r.first_seen = r.first_seen == 0 ? first : std::min(r.first_seen, first);
    r.last_seen = std::max(r.last_seen, last);
  };
  {
    Statement s(*writer_,
                "SELECT observer, sensor, COUNT(*), MIN(received_at), MAX(received_at) FROM scans "
                "GROUP BY observer, sensor");
    while (s.step()) {
      auto& r = robot(s.column_text(0));
      r.scans[s.column_text(1)] = s.column_int(2);
      seen(r, s.column_double(3), s.column_double(4));
    }
  }
  {
    Statement s(*writer_,
                "SELECT observer, COUNT(*), MIN(received_at), MAX(received_at) FROM observations "
                "WHERE kind = 'client' GROUP BY observer");
    while (s.step()) {
      auto& r = robot(s.column_text(0));
      r.primitives = s.column_int(1);
      seen(r, s.column_double(2), s.column_double(3));
    }
  }
  {
    Statement s(*writer_, "SELECT robot, COUNT(*), MIN(received_at), MAX(received_at) FROM robot_poses GROUP BY robot");
    while (s.step()) {
      auto& r = robot(s.column_text(0));
      r.poses = s.column_int(1);
      seen(r, s.column_double(2), s.column_double(3));
    }
  }
  for (auto& [id, r] : robots) {
    if (!r.scans.empty()) {
      Statement s(*writer_,
                  "SELECT seq, observer, stamp, scan, payload, received_at FROM scans WHERE observer = ?1 "
                  "ORDER BY seq DESC LIMIT 1");
      s.bind(1, std::string_view(id));
      if (s.step()) {
        try {
          r.last_scan = journaled_scan(s);
        } catch (const StorageError&) {
          // A damaged row: the robot comes back without its scan pose (the grid's replay says which row).
        }
        r.last_scan_received_at = s.column_double(5);
      }
    }
    Statement s(*writer_,
                "SELECT x, y, theta, cov, stamp, received_at, state FROM robot_poses WHERE robot = ?1 "
                "ORDER BY seq DESC LIMIT ?2");
    s.bind(1, std::string_view(id));
    s.bind(2, static_cast<std::int64_t>(track_points));
    while (s.step()) {
      RobotPoseEntry pose{id,           s.column_double(0), s.column_double(1), s.column_double(2),
                          std::nullopt, s.column_double(4), s.column_double(5), s.column_text(6)};
      if (!s.column_doubles(3).empty()) pose.cov = read_matrix<Eigen::Matrix3d>(s, 3);
      r.poses_newest_first.push_back(std::move(pose));
    }
  }
  std::vector<RobotJournal> out;
  for (auto& [id, r] : robots) out.push_back(std::move(r));
  return out;
}

std::int64_t Store::last_scan_seq() {
  std::lock_guard lock(writer_mutex_);
  return query_int(*writer_, "SELECT COALESCE(MAX(seq), 0) FROM scans");
}

bool Store::has_observation(const std::string& observer, const std::string& payload) {
  std::lock_guard lock(writer_mutex_);
  Statement s(*writer_, "SELECT 1 FROM observations WHERE observer = ?1 AND payload = ?2 LIMIT 1");
  s.bind(1, std::string_view(observer));
  s.bind(2, std::string_view(payload));
  return s.step();
}

std::vector<JournaledScan> Store::scans_after(std::int64_t after, std::size_t limit) {
  std::lock_guard lock(writer_mutex_);
  Statement s(*writer_, "SELECT seq, observer, stamp, scan, payload FROM scans WHERE seq > ?1 ORDER BY seq LIMIT ?2");
  s.bind(1, after);
  s.bind(2, static_cast<std::int64_t>(std::min<std::size_t>(limit, std::numeric_limits<std::int64_t>::max())));
  std::vector<JournaledScan> result;
  while (s.step()) result.push_back(journaled_scan(s));
  return result;
}

std::optional<JournaledScan> Store::scan(std::int64_t seq) {
  std::lock_guard lock(reader_mutex_);
  Statement s(*reader_, "SELECT seq, observer, stamp, scan, payload FROM scans WHERE seq = ?1");
  s.bind(1, seq);
  if (!s.step()) return std::nullopt;
  return journaled_scan(s);
}

std::int64_t Store::scans_missing_line_decisions() {
  std::lock_guard lock(reader_mutex_);
  return query_int(*reader_,
                   "SELECT COUNT(*) FROM scans WHERE lines_seq IS NOT NULL AND NOT EXISTS "
                   "(SELECT 1 FROM decisions d WHERE d.observation_seq = scans.lines_seq)");
}

}  // namespace wm::storage
