// The truth benchmark (tools/truth): the simulated world is what it claims to be, the scorer gives a perfect map full
// marks, and a drive through four real plans as built (walls demolished, partitions, the table moved, people) is
// scored without the plan (precision, recall, redundancy, elements per wall) and with it (demolished walls found,
// standing walls called missing, partitions found, the table's end pose, people). Whole routes, low pose noise; both
// noises are wm-truth's.
#include "tools/truth/truth.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "fusion/lines/scan_lines.h"
#include "tests/support/test_data.h"

namespace wm::truth {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

std::filesystem::path data_dir() {
  // Any file of the shared directory: real_data() fails the test with the path when it is missing.
  return testing::real_data("amrl-vectormaps/GDC1.vectormap.json").parent_path().parent_path();
}

double route_clearance(const Building& b, const std::vector<PlanWall>& walls) {
  double clearance = 1e9;
  for (const auto& line : b.route)
    for (std::size_t k = 0; k + 1 < line.size(); ++k)
      for (const auto& w : walls) clearance = std::min(clearance, segment_distance(line[k], line[k + 1], w.p0, w.p1));
  return clearance;
}

TEST(TruthWorldTest, EditsAreWhatTheyClaim) {
  for (const auto& name : building_names()) {
    const auto b = load_building(name, data_dir(), 1, 120);
    ASSERT_FALSE(b.route.empty()) << name;
    // The generated routes keep 0.5 m from walls (a raster cell's half diagonal of slack); GDC1's is its own.
    if (name != "gdc1") {
      EXPECT_GE(route_clearance(b, b.enclosure), 0.5 - 0.18) << name;
    }
    const auto world = build_world(b, Edits{}, 1);
    EXPECT_EQ(world.demolished.size(), 2u) << name;
    for (const auto& group : world.demolished) {
      const auto& w = b.walls[group.front()];
      const double length = (w.p1 - w.p0).norm();
      EXPECT_GE(length, 1.5) << name;
      EXPECT_LE(length, 5.0) << name;
      for (const auto& line : world.lines) EXPECT_NE(line.plan_wall, group.front()) << name << ": still standing";
    }
    ASSERT_EQ(world.partitions.size(), 2u) << name;
    for (const int p : world.partitions) {
      const auto& line = world.lines[p];
      EXPECT_GE((line.p1 - line.p0).norm(), 2.5 - 1e-9) << name;
      EXPECT_LE((line.p1 - line.p0).norm(), 3.5 + 1e-9) << name;
      for (const auto& w : b.walls) EXPECT_GE(segment_distance(line.p0, line.p1, w.p0, w.p1), 0.5) << name;
    }
    ASSERT_TRUE(world.table) << name;
    EXPECT_NEAR(std::hypot(world.table->x_m - b.table.x_m, world.table->y_m - b.table.y_m), std::hypot(0.25, 0.15),
                1e-9);
    EXPECT_NEAR(world.table->theta_rad - b.table.theta_rad, 10 * kDeg, 1e-3);
    ASSERT_EQ(world.people.size(), 3u) << name;
    for (const auto& person : world.people) {
      // Never standing still: within any 2 s, at least 0.5 m from where they were (1 m/s, turning at the ends).
      for (double t = 0; t < 30; t += 0.5) {
        double furthest = 0;
        for (double u = 0.25; u <= 2; u += 0.25)
          furthest = std::max(furthest, (person.at(t + u) - person.at(t)).norm());
        EXPECT_GE(furthest, 0.5) << name;
      }
    }
  }
}

TEST(TruthWorldTest, TheLaserSeesTheWallsAndThroughTheDemolishedOnes) {
  const auto b = load_building("gdc1", data_dir(), 1, 60);
  const auto world = build_world(b, Edits{}, 1);
  LaserOptions laser;
  laser.field_of_view_deg = 270;
  const auto d = drive(b, world, laser, 1);
  ASSERT_FALSE(d.scans.empty());
  EXPECT_EQ(d.scans.front().ranges_m.size(), 540u);  // 0.5° over 270°
  EXPECT_NEAR(d.scans.front().angle_min_rad, -135 * kDeg, 1e-12);
  double seen = 0, through = 0;
  for (const auto& bins : d.coverage.hits)
    for (const auto n : bins) seen += n > 0 ? kBinM : 0;
  for (const auto& group : d.coverage.seen_through)
    for (const auto& bins : group)
      for (const auto n : bins) through += n ? kBinM : 0;
  EXPECT_GT(seen, 100.0);
  EXPECT_GT(through, 0.0);
  // The posted poses carry the error, the ranges the truth.
  double error = 0;
  for (std::size_t k = 0; k < d.scans.size(); ++k)
    error += std::hypot(d.scans[k].sensor_pose.x_m - d.truth[k].x_m, d.scans[k].sensor_pose.y_m - d.truth[k].y_m);
  EXPECT_GT(error / static_cast<double>(d.scans.size()), 0.005);
  EXPECT_LT(error / static_cast<double>(d.scans.size()), 0.03);
}

TEST(TruthScoreTest, TheTrueLinesAsAMapScoreFullMarks) {
  const auto b = load_building("rmf-office", data_dir(), 1, 0);
  const auto world = build_world(b, Edits{}, 1);
  const auto d = drive(b, world, LaserOptions{}, 1);
  world::WorldState state;
  std::int64_t number = 1;
  std::vector<const TrueLine*> kept;
  for (const auto& line : world.lines) {
    // The office's plan draws some walls twice (a long wall and its pieces): one element for both, as a map would.
    const Vec mid = (line.p0 + line.p1) / 2;
    bool drawn = false;
    for (const auto* k : kept)
      drawn = drawn || (point_segment_distance(mid, k->p0, k->p1) < 0.05 &&
                        direction_difference(line.p1 - line.p0, k->p1 - k->p0) < 3 * kDeg);
    if (drawn) continue;
    kept.push_back(&line);
    world::Element e;
    e.number = number++;
    e.segment = fusion::LineSegment::from_points(line.p0, line.p1, Eigen::Matrix2d::Identity() * 1e-4);
    state.elements.put(std::move(e));
  }
  const auto s = score_mapping(state, world, d.coverage);
  EXPECT_NEAR(s.precision, 1.0, 1e-9);
  EXPECT_NEAR(s.recall, 1.0, 1e-9);
  EXPECT_NEAR(s.recall_all, 1.0, 1e-9);
  // Lines of the plan that meet at corners share a bin or two there.
  EXPECT_LT(s.redundancy, 0.01);
  EXPECT_NEAR(s.elements_per_wall, 1.0, 0.2);
  EXPECT_EQ(s.people_element_m, 0.0);
}

// The mapping recall leaves out walls shorter than the shortest line the scan line extractor makes, and only those.
TEST(TruthScoreTest, TheRecallLeavesOutOnlyWallsNoScanLineCanCover) {
  EXPECT_EQ(kShortestLineM, fusion::ScanLineOptions{}.min_length_m);
}

// The figures asked of a line map, per building, and where a building does not reach one today the figure it does
// reach (seed 1, low pose noise σ 1 cm / 0.2°, whole routes), so that the test fails on any regression and says
// plainly what is not met. wm-truth prints the same table for both pose noises.
struct Expected {
  const char* building;
  double precision, recall;        // targets 0.97, 0.90
  double demolished_found;         // target 0.95
  double new_found;                // target 1.00 (all of each partition's seen length)
  double max_table_error_m;        // target 0.03 (and 1°)
  std::size_t max_table_elements;  // target 0: the table's sides never become walls
};

// A building's name as a test name ("rmf-office" -> "rmf_office").
std::string test_name(std::string building) {
  for (auto& ch : building)
    if (ch == '-') ch = '_';
  return building;
}

// The mapping figures every drive must reach whatever the noise: precision and recall at least as given, redundancy
// at most 0.02, at most 1.2 elements per wall, and nothing left where people walked.
void expect_mapping(const MappingScore& m, double precision, double recall) {
  EXPECT_GE(m.precision, precision);
  EXPECT_GE(m.recall, recall);
  EXPECT_LE(m.redundancy, 0.02);
  EXPECT_LE(m.elements_per_wall, 1.2);
  EXPECT_EQ(m.people_element_m, 0.0);
}

class TruthBuildingTest : public ::testing::TestWithParam<Expected> {};

TEST_P(TruthBuildingTest, MapAndChangesAgainstTheBuildingAsBuilt) {
  const auto& e = GetParam();
  TruthOptions options;
  options.data_dir = data_dir();
  options.rules_dir = WM_RULES_DIR;
  const auto r = run_truth(e.building, options);
  std::printf("%s", format_table({r}).c_str());
  expect_mapping(r.mapping, e.precision, e.recall);
  ASSERT_TRUE(r.as_built);
  const auto& a = *r.as_built;
  ASSERT_TRUE(a.demolished_found && a.false_missing && a.people_missing_m);
  EXPECT_GE(*a.demolished_found, e.demolished_found);
  EXPECT_LE(*a.false_missing, 0.01);  // walls that stand and were in view, reported missing: ≤ 1 % of their length
  EXPECT_EQ(*a.people_missing_m, 0.0);
  EXPECT_EQ(a.people_element_m, 0.0);
  EXPECT_GE(a.new_found, e.new_found);
  EXPECT_LE(a.table_error_m, e.max_table_error_m);
  EXPECT_LE(a.table_edge_elements, e.max_table_elements);
}

// Reached (seed 1): precision 0.985-1.000 (the RMF office's curved facade, drawn as facets 6-9° apart, was seen as
// chords running past each bend at 0.965-0.973 over seeds 1-3 until elements were cut back at shallow corners; 0.992
// now), recall 0.903-0.987 (Barcelona: a 5 m wall seen only from 11-20 m at grazing angles; counting the 4-6 cm faces
// of its cruciform columns too, 0.862), demolished walls 0.993-1.000, partitions covered in full (a stretch counts as
// seen with at least three returns on it: GDC1's far 0.3 m of one, seen by one or two beams per 5 cm at 14° from 7 m,
// is not). The table (moved 0.29 m / 10°) ends within 1.7 cm / 0.1° everywhere.
INSTANTIATE_TEST_SUITE_P(Buildings, TruthBuildingTest,
                         ::testing::Values(Expected{"gdc1", 0.97, 0.90, 0.95, 1.00, 0.03, 0},
                                           Expected{"ahg2", 0.97, 0.95, 0.95, 1.00, 0.03, 0},
                                           Expected{"rmf-office", 0.97, 0.90, 0.95, 1.00, 0.03, 0},
                                           Expected{"barcelona", 0.97, 0.90, 0.95, 1.00, 0.03, 0}),
                         [](const auto& info) { return test_name(info.param.building); });

// The same drives with the pose posted at σ 3 cm / 0.5° (and its covariance), with the figures reached (seed 1) as
// the floor, so that what keeps noisy views on their walls (each scan aligned to the map before it is decided), the
// two faces of a wall apart and the table's far views on the table cannot quietly go. Reached: precision
// 0.970-0.997 (without the alignment 0.832-0.901; AHG2 0.935 before a short wall beside a long one, end to end, was
// kept apart as a depth step), recall 0.903-0.987, demolished walls found 0.993-1.000 (AHG2 0.878 before an edge sample
// the grid could not call free, crossed by many counted beams and returned on by few, was taken as seen through), the
// table within 3.6 cm / 0.2° and none of its sides a wall (two on Barcelona before a far view that ran 17 cm past the
// table's corner was taken as its side). Not met: precision in AHG2 (0.970 at three decimals, the floor below kept
// at 0.96; 0.968 before elements were cut back at shallow corners), the table on GDC1 (3.6 cm). The RMF office's curved
// wall, drawn as facets 6-9° apart: 0.971 before those cuts, 0.997 now.
struct ExpectedNoisy {
  const char* building;
  double precision, recall;
  double demolished_found;
  double max_table_error_m;
};

class TruthHighNoiseTest : public ::testing::TestWithParam<ExpectedNoisy> {};

TEST_P(TruthHighNoiseTest, NoisyPosesStillGiveOneElementPerWallAndTheChanges) {
  const auto& e = GetParam();
  TruthOptions options;
  options.data_dir = data_dir();
  options.rules_dir = WM_RULES_DIR;
  options.pose_noise = PoseNoise::high;
  const auto r = run_truth(e.building, options);
  std::printf("%s", format_table({r}).c_str());
  expect_mapping(r.mapping, e.precision, e.recall);
  ASSERT_TRUE(r.as_built);
  const auto& a = *r.as_built;
  ASSERT_TRUE(a.demolished_found && a.false_missing && a.people_missing_m);
  EXPECT_GE(*a.demolished_found, e.demolished_found);
  EXPECT_LE(*a.false_missing, 0.01);
  // AHG2 had 0.30 m here before a stretch had to be crossed by as many beams as returned on it (a 0.32 m wall
  // seen from both sides, its cells freed by the beams of each side).
  EXPECT_EQ(*a.people_missing_m, 0.0);
  EXPECT_EQ(a.people_element_m, 0.0);
  EXPECT_GE(a.new_found, 1.0);  // every partition in full, as at low noise
  EXPECT_LE(a.table_error_m, e.max_table_error_m);
  EXPECT_EQ(a.table_edge_elements, 0u);
}

INSTANTIATE_TEST_SUITE_P(Buildings, TruthHighNoiseTest,
                         ::testing::Values(ExpectedNoisy{"gdc1", 0.97, 0.90, 0.95, 0.04},
                                           ExpectedNoisy{"ahg2", 0.96, 0.95, 0.95, 0.03},
                                           ExpectedNoisy{"rmf-office", 0.98, 0.97, 0.95, 0.03},
                                           ExpectedNoisy{"barcelona", 0.99, 0.90, 0.95, 0.03}),
                         [](const auto& info) { return test_name(info.param.building); });

// The table moved as far as a not_deformable object is asked to be followed, 0.5 m or 20°, each way: it is found
// and placed within 3 cm / 1° and none of its sides stays as a wall. On the two buildings whose drives are short
// (the RMF office's and Barcelona's): every move ends within 1.1 cm / 0.2° there, and within 5 cm on GDC1 and AHG2.
struct TableMove {
  const char* name;
  const char* building;
  double dx_m, dy_m, dtheta_deg;
};

class TruthTableMoveTest : public ::testing::TestWithParam<TableMove> {};

TEST_P(TruthTableMoveTest, AMovedTableIsFoundAndPlacedWhereItStands) {
  const auto& m = GetParam();
  TruthOptions options;
  options.data_dir = data_dir();
  options.rules_dir = WM_RULES_DIR;
  options.edits.table_shift = {m.dx_m, m.dy_m, m.dtheta_deg * kDeg};
  const auto r = run_truth(m.building, options);
  std::printf("%s", format_table({r}).c_str());
  ASSERT_TRUE(r.as_built);
  EXPECT_FALSE(r.as_built->table_removed);
  EXPECT_LE(r.as_built->table_error_m, 0.03);
  EXPECT_LE(r.as_built->table_error_deg, 1.0);
  EXPECT_EQ(r.as_built->table_edge_elements, 0u);
}

INSTANTIATE_TEST_SUITE_P(
    Moves, TruthTableMoveTest,
    ::testing::Values(TableMove{"rmf_office_west_half_metre_clockwise", "rmf-office", -0.5, 0, -20},
                      TableMove{"rmf_office_diagonal_half_metre_anticlockwise", "rmf-office", 0.35, 0.35, 20},
                      TableMove{"rmf_office_north_half_metre_clockwise", "rmf-office", 0, 0.5, -20},
                      TableMove{"rmf_office_east_half_metre_anticlockwise", "rmf-office", 0.5, 0, 20},
                      TableMove{"barcelona_west_half_metre_clockwise", "barcelona", -0.5, 0, -20},
                      TableMove{"barcelona_diagonal_half_metre_anticlockwise", "barcelona", 0.35, 0.35, 20},
                      TableMove{"barcelona_north_half_metre_clockwise", "barcelona", 0, 0.5, -20},
                      TableMove{"barcelona_east_half_metre_anticlockwise", "barcelona", 0.5, 0, 20}),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace wm::truth
