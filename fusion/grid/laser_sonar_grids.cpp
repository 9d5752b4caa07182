#include "fusion/grid/laser_sonar_grids.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace wm::fusion {
namespace {

constexpr float kUnknown = std::numeric_limits<float>::quiet_NaN();

/// The decision layer of `grid` over `region`, from its own belief, plausibility and conflict layers.
std::vector<float> decision_layer(const OccupancyGrid& grid, const GridGeometry& region,
                                  const DsDecisionOptions& options) {
  auto belief = grid.export_layer(OccupancyGrid::Layer::ds_belief, region);
  const auto plausibility = grid.export_layer(OccupancyGrid::Layer::ds_plausibility, region);
  const auto conflict = grid.export_layer(OccupancyGrid::Layer::ds_conflict, region);
  for (std::size_t i = 0; i < belief.size(); ++i) {
    if (std::isnan(belief[i])) continue;
    const double o = belief[i], e = 1.0 - plausibility[i];
    belief[i] = ds_decision_value(ds_decision({o, e, 1.0 - o - e}, conflict[i], options));
  }
  return belief;
}

}  // namespace

void validate(const DsDecisionOptions& options) {
  if (!(options.occupied_belief_min > 0 && options.occupied_belief_min <= 1))
    throw std::invalid_argument("DsDecisionOptions::occupied_belief_min must be in (0, 1]");
  if (!(options.free_plausibility_max >= 0 && options.free_plausibility_max < 1))
    throw std::invalid_argument("DsDecisionOptions::free_plausibility_max must be in [0, 1)");
  if (!(options.conflict_min > 0 && std::isfinite(options.conflict_min)))
    throw std::invalid_argument("DsDecisionOptions::conflict_min must be a number above 0 (above 1: never)");
}

DsDecision ds_decision(const OccupancyGrid::Masses& masses, double conflict, const DsDecisionOptions& options) {
  if (conflict >= options.conflict_min) return DsDecision::conflict;
  if (masses.occupied >= options.occupied_belief_min) return DsDecision::occupied;
  if (1.0 - masses.empty <= options.free_plausibility_max) return DsDecision::free;
  return DsDecision::undecided;
}

float ds_decision_value(DsDecision decision) {
  switch (decision) {
    case DsDecision::free:
      return 0.0f;
    case DsDecision::undecided:
      return 0.5f;
    case DsDecision::conflict:
      return 0.75f;
    case DsDecision::occupied:
      return 1.0f;
  }
  return kUnknown;
}

std::string_view to_string(GridLayer layer) { return kGridLayerNames.at(static_cast<std::size_t>(layer)); }

std::optional<OccupancyGrid::Layer> stored_layer(GridLayer layer) {
  switch (layer) {
    case GridLayer::bayes:
      return OccupancyGrid::Layer::bayes_probability;
    case GridLayer::ds_belief:
      return OccupancyGrid::Layer::ds_belief;
    case GridLayer::ds_plausibility:
      return OccupancyGrid::Layer::ds_plausibility;
    case GridLayer::ds_conflict:
      return OccupancyGrid::Layer::ds_conflict;
    default:
      return std::nullopt;
  }
}

std::optional<GridLayer> grid_layer_named(std::string_view name) {
  for (std::size_t i = 0; i < kGridLayerNames.size(); ++i)
    if (kGridLayerNames[i] == name) return static_cast<GridLayer>(i);
  return std::nullopt;
}

void validate(const LaserSonarOptions& options) {
  if (options.recent_laser_scans > 64)
    throw std::invalid_argument("LaserSonarOptions::recent_laser_scans must be <= 64");
  validate(options.gate);
  validate(options.decision);
}

LaserSonarGrids::LaserSonarGrids(const GridOptions& grid, const LaserSonarOptions& options)
    : grid_options_(grid), options_(options), fused_(grid) {
  validate(options_);
  grid_options_ = fused_.options();
}

LaserSonarGrids::LaserSonarGrids(const LaserSonarGrids& other)
    : grid_options_(other.grid_options_),
      options_(other.options_),
      fused_(other.fused_),
      laser_(other.laser_ ? std::make_unique<OccupancyGrid>(*other.laser_) : nullptr),
      sonar_(other.sonar_ ? std::make_unique<OccupancyGrid>(*other.sonar_) : nullptr),
      counts_(other.counts_),
      recent_(other.recent_) {}

LaserSonarGrids& LaserSonarGrids::operator=(const LaserSonarGrids& other) {
  if (this != &other) {
    LaserSonarGrids copy(other);
    *this = std::move(copy);
  }
  return *this;
}

void LaserSonarGrids::start_sides(bool copy_fused) {
  if (sonar_) return;
  laser_ = copy_fused ? std::make_unique<OccupancyGrid>(fused_) : std::make_unique<OccupancyGrid>(grid_options_);
  sonar_ = std::make_unique<OccupancyGrid>(grid_options_);
}

void LaserSonarGrids::start_side_grids() { start_sides(false); }

void LaserSonarGrids::insert(const LaserScan& scan) {
  fused_.insert(scan);
  if (laser_) laser_->insert(scan);
  remember_returns(scan);
}

void LaserSonarGrids::remember_returns(const LaserScan& scan) {
  if (options_.recent_laser_scans == 0) return;
  std::vector<Eigen::Vector2d> points;
  const double reach = std::min(scan.range_max_m, usable_range_m(scan, grid_options_.sensor));
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double r = scan.ranges_m[i];
    if (!(r >= scan.range_min_m && r < reach)) continue;
    const double a =
        scan.sensor_pose.theta_rad + scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
    points.emplace_back(scan.sensor_pose.x_m + r * std::cos(a), scan.sensor_pose.y_m + r * std::sin(a));
  }
  recent_.push_back(std::move(points));
  if (recent_.size() > options_.recent_laser_scans) recent_.erase(recent_.begin());
}

SonarGateResult LaserSonarGrids::insert(const SonarScan& scan) {
  validate(scan);
  start_sides(true);
  const auto gated = judge(scan);
  // The fused grid first: its tiles cover the sonar-only grid's, so the sonar grid's growth check passes whenever
  // the fused one's did, and a refused scan changes neither.
  fused_.insert(scan, gated.beams);
  sonar_->insert(scan);
  count(gated);
  return gated;
}

void LaserSonarGrids::insert_side_only(const LaserScan& scan) {
  if (laser_) laser_->insert(scan);
  remember_returns(scan);
}

void LaserSonarGrids::insert_side_only(const SonarScan& scan) {
  validate(scan);
  start_sides(false);
  const auto gated = judge(scan);
  sonar_->insert(scan);
  count(gated);
}

SonarGateResult LaserSonarGrids::judge(const SonarScan& scan) const {
  if (options_.gate_sonar) {
    // Put together here, per sonar scan, rather than per laser scan: a map without sonar never needs it.
    std::vector<Eigen::Vector2d> recent;
    for (const auto& points : recent_) recent.insert(recent.end(), points.begin(), points.end());
    return gate_sonar(scan, *laser_, options_.gate, recent);
  }
  SonarGateResult kept;
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    kept.beams.push_back(sonar_beam(scan, i, grid_options_.sensor));
    kept.verdicts.push_back(kept.beams.back() ? SonarVerdict::kept : SonarVerdict::ignored);
  }
  return kept;
}

void LaserSonarGrids::count(const SonarGateResult& gated) {
  ++counts_.scans;
  counts_.kept += gated.count(SonarVerdict::kept);
  counts_.unjudged += gated.count(SonarVerdict::unjudged);
  counts_.phantom += gated.count(SonarVerdict::phantom);
  counts_.clipped += gated.count(SonarVerdict::clipped);
  counts_.ignored += gated.count(SonarVerdict::ignored);
}

std::vector<float> LaserSonarGrids::export_layer(GridLayer layer, const GridGeometry& region) const {
  switch (layer) {
    case GridLayer::bayes:
      return fused_.export_layer(OccupancyGrid::Layer::bayes_probability, region);
    case GridLayer::ds_belief:
      return fused_.export_layer(OccupancyGrid::Layer::ds_belief, region);
    case GridLayer::ds_plausibility:
      return fused_.export_layer(OccupancyGrid::Layer::ds_plausibility, region);
    case GridLayer::ds_conflict:
      return fused_.export_layer(OccupancyGrid::Layer::ds_conflict, region);
    case GridLayer::ds_decision:
      return decision_layer(fused_, region, options_.decision);
    case GridLayer::laser_bayes:
      return laser_only().export_layer(OccupancyGrid::Layer::bayes_probability, region);
    case GridLayer::laser_ds_decision:
      return decision_layer(laser_only(), region, options_.decision);
    case GridLayer::sonar_bayes:
      if (sonar_) return sonar_->export_layer(OccupancyGrid::Layer::bayes_probability, region);
      break;
    case GridLayer::laser_sonar_conflict:
      if (sonar_) {
        // K = m_L(O)·m_S(E) + m_L(E)·m_S(O), where both sensors have seen the cell.
        auto laser_belief = laser_->export_layer(OccupancyGrid::Layer::ds_belief, region);
        const auto laser_plausibility = laser_->export_layer(OccupancyGrid::Layer::ds_plausibility, region);
        const auto sonar_belief = sonar_->export_layer(OccupancyGrid::Layer::ds_belief, region);
        const auto sonar_plausibility = sonar_->export_layer(OccupancyGrid::Layer::ds_plausibility, region);
        for (std::size_t i = 0; i < laser_belief.size(); ++i) {
          if (std::isnan(laser_belief[i]) || std::isnan(sonar_belief[i])) {
            laser_belief[i] = kUnknown;
            continue;
          }
          laser_belief[i] =
              laser_belief[i] * (1.0f - sonar_plausibility[i]) + (1.0f - laser_plausibility[i]) * sonar_belief[i];
        }
        return laser_belief;
      }
      break;
  }
  if (region.width() > OccupancyGrid::kMaxExportCells / region.height())
    throw std::invalid_argument("LaserSonarGrids::export_layer: region has more than " +
                                std::to_string(OccupancyGrid::kMaxExportCells) + " cells");
  return std::vector<float>(static_cast<std::size_t>(region.width() * region.height()), kUnknown);
}

std::uint64_t LaserSonarGrids::tile_revision(GridLayer layer, TileIndex t) const {
  // Every layer has a tile wherever the fused grid has one (a viewer reads the fused grid's tile index for all of
  // them). Revisions only grow, so the sum of the revisions of the grids a layer reads changes whenever one does.
  const auto fused = fused_.tile_revision(t);
  if (fused == 0) return 0;
  switch (layer) {
    case GridLayer::bayes:
    case GridLayer::ds_belief:
    case GridLayer::ds_plausibility:
    case GridLayer::ds_conflict:
    case GridLayer::ds_decision:
      return fused;
    case GridLayer::laser_bayes:
    case GridLayer::laser_ds_decision:
      return laser_ ? fused + laser_->tile_revision(t) : fused;
    case GridLayer::sonar_bayes:
      return sonar_ ? fused + sonar_->tile_revision(t) : fused;
    case GridLayer::laser_sonar_conflict:
      return sonar_ ? fused + sonar_->tile_revision(t) + laser_->tile_revision(t) : fused;
  }
  return fused;
}

}  // namespace wm::fusion
