#pragma once

// The simulated building of the truth benchmark: a real plan's walls (the plan as drawn), the world as built (the
// plan with walls demolished, partitions added, the table moved, people walking), a route through it and the laser
// scans a robot driving it would take. Pure geometry: no service, no store.
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "apriori/floor_plan.h"
#include "fusion/geometry/pose2d.h"
#include "fusion/grid/scan.h"

namespace wm::truth {

using Vec = Eigen::Vector2d;
using Polyline = std::vector<Vec>;

/// One edge of a `solid` plan object, in the world frame as drawn [m].
struct PlanWall {
  std::string object_id;
  std::size_t edge = 0;  // index in the object's edges()
  Vec p0, p1;
};

inline constexpr double kTableLengthM = 1.2, kTableWidthM = 0.8;
inline constexpr const char* kTableId = "truth-table";

/// A building's plan and the robot's route through it.
struct Building {
  std::string name;
  apriori::FloorPlan plan;      // the solid walls as drawn, plus the table (`not_deformable`, id kTableId)
  std::vector<PlanWall> walls;  // every edge of the plan's walls (not the table's)
  /// The walls and the glass walls: what the route, the table, partitions and people keep clear of, and what
  /// encloses the building (glass is in neither the plan nor the simulated world: a laser sees through it).
  std::vector<PlanWall> enclosure;
  std::vector<Polyline> route;  // driven in order; the robot jumps between polylines [m]
  fusion::Pose2D table;         // the table's pose in the plan
};

/// The buildings wm-truth knows: gdc1, ahg2, rmf-office, barcelona.
std::vector<std::string> building_names();

/// Loads `name` from the shared data directory (amrl-vectormaps/, rmf-office/, barcelona-pavilion/). Walls are the
/// `solid` objects without `glass` (a laser sees through glass, so a glass wall could never be confirmed), doors are
/// open and furniture is left out. GDC1 drives raycast::gdc1_route(); the others a route built from a 0.25 m
/// raster of the walls (see auto_route). `max_route_m` > 0 keeps only the first that many metres of the route. The
/// table is placed beside the route, clear of the walls and of the route by 0.7 m.
/// @throw std::runtime_error for an unknown name, a missing file or a building without room for the table.
Building load_building(const std::string& name, const std::filesystem::path& data_dir, unsigned seed,
                       double max_route_m = 0);

/// A route through the free space of `walls`: cells of a 0.25 m raster at least 0.5 m from every wall and inside the
/// building (at least 6 of 8 rays from them hit a wall within 40 m), the largest connected part of them, targets in
/// it at least 4 m apart, visited nearest first (by path length) along shortest paths that keep away from walls,
/// each path shortened to straight runs that stay in free cells. One polyline [m].
Polyline auto_route(const std::vector<PlanWall>& walls, unsigned seed);

/// What a line of the world as built is.
enum class LineKind { wall, partition, table };

struct TrueLine {
  Vec p0, p1;
  LineKind kind = LineKind::wall;
  int plan_wall = -1;  // index in Building::walls for walls of the plan
};

/// A person walking back and forth along a track at a constant speed, a disc of 0.4 m diameter.
struct Person {
  Vec a, b;              // the track's ends [m]
  double phase_m = 0;    // where along the walk (a → b → a) it is at t = 0 [m]
  double speed_mps = 1;  // [m/s], never 0: nobody stands still for long
  /// Where the person is at time t [s].
  Vec at(double t_s) const;
};

inline constexpr double kPersonRadiusM = 0.2;

/// The edits of the world as built (the plan stays as drawn).
struct Edits {
  std::size_t demolished = 2;  // plan walls of 1.5–5 m the route sees well, removed (with their other face)
  std::size_t partitions = 2;  // new 2.5–3.5 m walls in free space near the route
  bool table_removed = false;
  /// The table's displacement: x, y [m] in the world and θ [rad] about its centre.
  Eigen::Vector3d table_shift{0.25, 0.15, 0.1745};
  std::size_t people = 3;
  double person_speed_mps = 1.0;
};

/// The world as built.
struct BuiltWorld {
  std::vector<TrueLine> lines;               // what the laser hits, people aside
  std::vector<std::vector<int>> demolished;  // per demolished wall: its plan walls (a face and its other face)
  std::vector<int> partitions;               // indices in `lines`
  std::optional<fusion::Pose2D> table;       // its true pose; nullopt when removed
  std::vector<Person> people;
};

/// Applies `edits` to the building (seeded).  @throw std::runtime_error when no place is found for an edit.
BuiltWorld build_world(const Building& building, const Edits& edits, unsigned seed);

/// The table's outline at `pose` (four sides).
std::vector<std::pair<Vec, Vec>> table_sides(const fusion::Pose2D& pose);

struct LaserOptions {
  double step_m = 0.3;           // between scans along the route [m]
  double robot_speed_mps = 0.6;  // how fast the robot drives (people move between scans by this) [m/s]
  double field_of_view_deg = 360;
  double beam_step_deg = 0.5;
  double max_range_m = 20;
  double sigma_range_m = 0.01;
  double sigma_xy_m = 0.01;         // the posted pose's error (and the covariance posted with it)
  double sigma_theta_rad = 0.0035;  // 0.2°
};

/// Sample spacing along true lines for what the laser saw [m].
inline constexpr double kBinM = 0.05;

/// Walls shorter than this are not counted in the mapping recall: the scan line extractor makes no line shorter
/// (its default minimum length), so the faces of a column or a door frame are the grid's to map, not the line map's.
/// MappingScore::recall_all counts them too.
inline constexpr double kShortestLineM = 0.3;

/// What the drive saw of each line.
/// Beams closer than this to running along a wall are not counted as seeing through it [rad] (10°).
inline constexpr double kMinIncidenceRad = 0.1745;
/// ... nor beams whose return lies less than this beyond it, across the wall [m]: a standing surface that close
/// behind a drawn line (AHG2 draws a wall's faces and frames as parallel lines 2-15 cm apart, some of which stay) is,
/// to any laser, that wall; the beam did not see space where the wall was.
inline constexpr double kMinDepthBeyondM = 0.15;
/// A stretch of a demolished wall counts as seen through when this many beams went through it: the grid needs
/// about three views of free space before a cell is free.
inline constexpr std::uint32_t kMinBeamsThrough = 3;
/// A stretch of a new partition counts as seen when this many returns fell on it over the whole drive, the count a
/// demolished wall's stretch needs to count as seen through: one or two returns at a grazing angle, 0.3 m apart, are
/// not a line to a line fitter, nor occupied to the grid.
inline constexpr std::uint32_t kMinReturnsSeen = 3;

struct Coverage {
  std::vector<std::vector<std::uint32_t>> hits;  // per BuiltWorld::lines, per kBinM bin: returns on it
  /// Per BuiltWorld::demolished, per plan wall of it, per bin: the beams that went through it at an incidence of
  /// at least kMinIncidenceRad (a beam running along a wall does not see whether it is there).
  std::vector<std::vector<std::vector<std::uint32_t>>> seen_through;
};

struct Drive {
  std::vector<fusion::LaserScan> scans;  // sensor_pose: the noisy pose the robot would post
  std::vector<fusion::Pose2D> truth;     // the true poses
  Coverage coverage;
  double route_m = 0;
};

/// Drives the route through the world as built, scanning every step (seeded noise).
Drive drive(const Building& building, const BuiltWorld& world, const LaserOptions& options, unsigned seed);

// Geometry shared with the scoring.
double point_segment_distance(const Vec& p, const Vec& a, const Vec& b);
double segment_distance(const Vec& a0, const Vec& a1, const Vec& b0, const Vec& b1);
/// Angle between two undirected directions, in [0, π/2] [rad].
double direction_difference(const Vec& d0, const Vec& d1);
/// Bins of a line of length `length_m` (at least one).
std::size_t bins_of(double length_m);

}  // namespace wm::truth
