// What the ingest's stages do to one request: its request id, a scan's lines, its events, the grid trim.
#include <algorithm>
#include <cmath>
#include <limits>
#include <variant>

#include "fusion/grid/scan_geometry.h"
#include "server/json/events_json.h"
#include "server/service/ingest_pipeline.h"
#include "server/service/knowledge_facts.h"
#include "server/service/service_errors.h"
#include "server/world/scan_alignment.h"

namespace wm::service {

// FNV-1a: not a defence against a client that crafts collisions, which could only confuse its own requests.
std::int64_t IngestPipeline::body_hash(std::string_view body) {
  std::uint64_t h = 14695981039346656037ull;
  for (const unsigned char c : body) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return static_cast<std::int64_t>(h);
}

void add_robot_event(EventLog::Commit& live, const RobotRegistry& robots, const std::optional<RobotState>& robot) {
  if (!robot) return;
  const double now = now_unix_s();
  live.add(events::EventKind::robot,
           [&] { return json_codec::robot_event(*robot, to_string(robots.status(*robot, now)), now); });
}

world::Observation IngestPipeline::grid_lines_observation(const std::vector<fusion::LineSegment>& segments) {
  world::Observation observation;
  observation.observer = "grid-extractor";
  observation.origin = "grid";
  observation.sensor = "grid";
  for (const auto& segment : segments) observation.segments.push_back({segment});
  return observation;
}

std::shared_ptr<const world::WorldState> IngestPipeline::head() const {
  return in_flight_ > 0 ? head_ : writer_.snapshot();
}

void IngestPipeline::refresh_head() {
  // With nothing in flight the published map is the head (a command may have changed it); a request that changes
  // nothing (a sonar scan, a scan without lines) still goes in flight, and the next one chains from this.
  if (in_flight_ == 0) head_ = writer_.snapshot();
}

std::optional<storage::RequestRecord> IngestPipeline::known_request(const std::string& request_id,
                                                                    std::string_view kind, std::int64_t hash) {
  auto record = store_.find_request(request_id);
  if (!record) return std::nullopt;
  if (record->kind != kind)
    throw RequestIdConflict("request id '" + request_id + "' was used for a " + record->kind + " request");
  if (record->body_hash != hash)
    throw RequestIdConflict("request id '" + request_id + "' was used with another body (" + record->kind + " " +
                            std::to_string(record->seq) + ")");
  return record;
}

std::optional<ScanOutcome> IngestPipeline::replayed_scan(const std::optional<std::string>& request_id,
                                                         std::int64_t hash, const world::ScanObservation& retried) {
  if (!request_id) return std::nullopt;
  const auto known = known_request(*request_id, "scan", hash);
  if (!known) return std::nullopt;
  ScanOutcome outcome{known->seq, known->grid_revision, std::nullopt, true, std::nullopt};
  if (known->lines_seq)
    outcome.lines =
        PrimitivesOutcome{*known->lines_seq, known->version, store_.observation_decisions(*known->lines_seq), true};
  // The retry posts the same bytes, so the same pose; the journal holds where the first one was placed.
  const auto* posted = std::get_if<fusion::LaserScan>(&retried.scan);
  if (options_.extract_scan_lines && posted) {
    if (const auto journaled = store_.scan(known->seq); journaled && journaled->scan)
      if (const auto* placed = std::get_if<fusion::LaserScan>(&journaled->scan->scan))
        outcome.placement = ScanPlacement{posted->sensor_pose, placed->sensor_pose};
  }
  return outcome;
}

namespace {

// A reading that is a return: no return (>= range_max) and invalid readings carry no surface.
bool is_return(const fusion::LaserScan& laser, double r) {
  return std::isfinite(r) && r >= laser.range_min_m && r < laser.range_max_m && r > 0;
}

}  // namespace

std::optional<PreparedUpdate> IngestPipeline::prepare_scan_lines(world::ScanObservation& scan,
                                                                 std::optional<ScanPlacement>& placement) {
  auto* laser = std::get_if<fusion::LaserScan>(&scan.scan);
  if (!options_.extract_scan_lines || !laser) return std::nullopt;
  std::vector<fusion::RangeReading> readings;
  for (std::size_t i = 0; i < laser->ranges_m.size(); ++i) {
    const double r = laser->ranges_m[i];
    if (is_return(*laser, r)) readings.push_back({r, fusion::beam_bearing_rad(*laser, i)});
  }
  placement = ScanPlacement{laser->sensor_pose, laser->sensor_pose};
  auto line_options = options_.scan_lines;
  line_options.sigma_range_m = laser->sigma_range_m;
  line_options.sigma_range_relative = laser->sigma_range_per_m;
  line_options.bearing_step_rad = std::abs(laser->angle_increment_rad);
  // In the sensor's own frame first (the sensor's noise only), so that they can place the sensor.
  const auto local = fusion::extract_scan_lines(readings, fusion::Pose2D{}, Eigen::Matrix3d::Zero(), line_options);
  if (local.empty()) return std::nullopt;
  if (options_.align_scans) {
    const auto alignment = world::align_to_map(*head_, local, laser->sensor_pose, scan.pose_cov,
                                               writer_.options().world, options_.scan_alignment);
    if (alignment.aligned) {
      placement->placed = alignment.pose;
      laser->sensor_pose = alignment.pose;
    }
  }
  world::Observation observation;
  observation.observer = scan.observer;
  observation.origin = "scan";
  observation.sensor = "laser";
  observation.stamp_s = scan.stamp_s;
  // Which face of each wall the laser saw: the two faces of a thin wall are kept apart by it.
  const Eigen::Vector2d viewpoint(laser->sensor_pose.x_m, laser->sensor_pose.y_m);
  for (const auto& segment : local) {
    const auto placed = fusion::transform_segment(segment, laser->sensor_pose, scan.pose_cov);
    observation.segments.push_back({placed, world::facing_toward(placed, viewpoint)});
  }
  if (options_.continue_lines)
    for (auto& view : continuations(*laser, local, line_options, scan.pose_cov)) {
      world::ObservedSegment continued(view.segment, world::facing_toward(view.segment, viewpoint));
      continued.continues = view.element;
      observation.segments.push_back(std::move(continued));
    }
  return writer_.prepare(head(), std::move(observation));
}

std::vector<world::ScanContinuation> IngestPipeline::continuations(const fusion::LaserScan& laser,
                                                                   const std::vector<fusion::LineSegment>& local,
                                                                   const fusion::ScanLineOptions& line_options,
                                                                   const Eigen::Matrix3d& pose_cov) const {
  auto options = options_.line_continuation;
  options.bearing_step_rad = std::abs(laser.angle_increment_rad);
  options.max_range_m = std::min(options.max_range_m, laser.range_max_m);
  options.sigma_range_m = line_options.sigma_range_m;
  options.sigma_range_relative = line_options.sigma_range_relative;
  options.sigma_bearing_rad = line_options.sigma_bearing_rad;
  std::vector<fusion::ContinuationBeam> beams;
  beams.reserve(laser.ranges_m.size());
  for (std::size_t i = 0; i < laser.ranges_m.size(); ++i) {
    const double r = laser.ranges_m[i];
    const double bearing = fusion::beam_bearing_rad(laser, i);
    if (is_return(laser, r)) {
      // A return on one of the scan's own lines is that line's: the continuation steps over it.
      const Eigen::Vector2d p(r * std::cos(bearing), r * std::sin(bearing));
      const bool claimed = std::any_of(local.begin(), local.end(), [&](const fusion::LineSegment& s) {
        const double t = s.line.coordinate_along(p);
        return t >= s.t0_m - line_options.split_distance_m && t <= s.t1_m + line_options.split_distance_m &&
               std::abs(s.line.signed_distance(p)) <= line_options.split_distance_m;
      });
      beams.push_back(fusion::ContinuationBeam::at(bearing, r, claimed));
    } else if (r >= laser.range_max_m) {
      beams.push_back(fusion::ContinuationBeam::at(bearing, std::numeric_limits<double>::infinity()));
    }
  }
  if (laser.angle_increment_rad < 0) std::reverse(beams.begin(), beams.end());  // in increasing bearing order
  return world::scan_continuations(*head_, beams, laser.sensor_pose, pose_cov, options);
}

void IngestPipeline::add_scan_event(EventLog::Commit& live, const world::ScanObservation& scan, std::int64_t seq) {
  live.add(events::EventKind::scan, [&] {
    constexpr std::size_t kMaxEventPoints = 360;
    const auto changed = grid_.changed_region(scan, 2 * grid_.resolution_m());
    const auto [pose, points] = std::visit(
        [&](const auto& s) {
          return std::pair{s.sensor_pose, fusion::scan_returns(s, kMaxEventPoints)};
        },
        scan.scan);
    return json_codec::scan_event(seq, scan.observer, scan.sensor(), pose, changed, points);
  });
}

void IngestPipeline::add_to_trim_region(const world::ScanObservation& scan) {
  // A cell more than the event's region: the trim probes a 3×3 neighbourhood.
  const auto box = grid_.changed_region(scan, 3 * grid_.resolution_m());
  const world::Box seen{box.min().x(), box.min().y(), box.max().x(), box.max().y()};
  std::lock_guard lock(trim_mutex_);
  if (!trim_region_) trim_region_ = seen;
  trim_region_ = world::Box{std::min(trim_region_->x0, seen.x0), std::min(trim_region_->y0, seen.y0),
                            std::max(trim_region_->x1, seen.x1), std::max(trim_region_->y1, seen.y1)};
}

void IngestPipeline::trim_now(std::int64_t scan_seq, const world::Box& region) {
  try {
    auto p = prepare_trim(region);
    if (!p) return;
    const auto payload = trim_payload(scan_seq);
    writer_.commit(*p, [&] { store_.commit_observation(p->update, p->observation, payload); });
    auto live = events_.begin();
    writer_.finish(std::move(*p), live);
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::error, "grid_trim",
                        "the grid trim of scan " + std::to_string(scan_seq) + " was not applied: " + e.what());
  }
}

std::optional<PreparedUpdate> IngestPipeline::prepare_trim(const world::Box& region) {
  try {
    auto p = MapWriter::own_observation(head(), kTrimObserver, "grid", "grid");
    std::vector<world::GridShares> checked;
    grid_.read([&](const fusion::OccupancyGrid& grid) {
      const double resolution = grid.resolution_m();
      fusion::OccupancyGrid::CellReader cells(grid);  // the samples of an element lie in a few tiles
      const auto probe = grid_element_probe(cells, resolution);
      auto trim = options_.grid_trim;
      trim.step_m = resolution;
      auto trimmed = world::trim_to_grid(*p.base, region, probe, p.seq, p.observation.observer, trim);
      p.update = std::move(trimmed.update);
      checked = std::move(trimmed.checked);
    });
    // The plan's edges the same scans could see: the evidence of missing walls follows the grid.
    plan_checks_.refresh(*p.base, region);
    // The trimmed elements' facts first (that drops their old element_grid/3), then what the grid said of every
    // element checked: the rules' prune/3 may remove what the grid backs nowhere.
    writer_.follow_elements(p.update, false);
    std::vector<rules::ElementGridFacts> grid_facts;
    grid_facts.reserve(checked.size());
    for (const auto& c : checked) grid_facts.push_back({world::element_id(c.number), c.backed, c.contrary});
    engine_.set_element_grid(grid_facts);
    writer_.prune(p, p.observation.observer);
    if (p.update.decisions.empty()) return std::nullopt;
    return p;
  } catch (const std::exception& e) {
    diagnostics_.report(common::Severity::warning, "grid_trim", std::string("grid trim failed: ") + e.what());
    writer_.restore_facts(*head(), "the failed grid trim");  // the rules see the map as decided before the trim
  }
  return std::nullopt;
}

std::optional<PrimitivesOutcome> IngestPipeline::extract_grid_lines() {
  const auto raster = grid_.probability_raster();
  if (!raster) return std::nullopt;
  const auto segments = fusion::extract_grid_lines(*raster, options_.grid_lines);
  if (segments.empty()) return std::nullopt;
  return apply(grid_lines_observation(segments), grid_lines_payload(grid_.revision()));
}

PrimitivesOutcome IngestPipeline::apply(world::Observation observation, const std::string& payload) {
  auto prepared = writer_.prepare(head(), std::move(observation));
  writer_.commit(prepared, [&] { store_.commit_observation(prepared.update, prepared.observation, payload); });
  auto live = events_.begin();
  return writer_.finish(std::move(prepared), live);
}

void IngestPipeline::trim_left_undone() {
  if (!trim_left_undone_) return;
  const auto [scan_seq, region] = *trim_left_undone_;
  trim_left_undone_.reset();
  trim_now(scan_seq, region);
}

}  // namespace wm::service
