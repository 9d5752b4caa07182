// plan_evidence against a grid given as a function of the point: shares, stretches, regions.
#include "server/world/plan_evidence.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace wm::world {
namespace {

// Wall "w" from (0, 0) to (4, 0); a table "t" (1 × 0.5 m) at (10, 10).
WorldState plan_state() {
  apriori::FloorPlan plan;
  plan.name = "test";
  apriori::PlanObject wall;
  wall.id = "w";
  wall.kind = "wall";
  wall.attributes = {"solid"};
  wall.polylines = {{{0, 0}, {4, 0}}};
  apriori::PlanObject table;
  table.id = "t";
  table.kind = "table";
  table.attributes = {"not_deformable"};
  table.pose = {10, 10, 0};
  table.polygon = {{-0.5, -0.25}, {0.5, -0.25}, {0.5, 0.25}, {-0.5, 0.25}};
  plan.objects = {wall, table};
  WorldState state;
  state.objects = ObjectTable(make_objects(plan, WorldOptions{}, 1));
  return state;
}

PlanEvidenceOptions options() {
  PlanEvidenceOptions o;
  o.step_m = 0.05;
  o.min_stretch_m = 0.3;
  o.max_unknown_gap = 2;
  return o;
}

TEST(PlanEvidenceTest, SharesAndStretchesFollowTheProbe) {
  const auto state = plan_state();
  // The wall stands from x = 0 to 1.5 and from 2.5 to 4 (a door cut in between, seen through); the table is unseen.
  const EdgeProbe probe = [](const Eigen::Vector2d& p, const Eigen::Vector2d&) {
    if (p.y() > 5) return EdgeSample::unknown;
    return p.x() > 1.5 && p.x() < 2.5 ? EdgeSample::seen_through : EdgeSample::backed;
  };
  const auto all = plan_evidence(state, probe, options());
  ASSERT_EQ(all.size(), 5u);  // the wall, the table's four sides
  const auto& wall = all[0];
  EXPECT_EQ(wall.object, 0u);
  EXPECT_EQ(wall.edge, 0u);
  EXPECT_NEAR(wall.length_m, 4.0, 1e-9);
  EXPECT_NEAR(wall.seen_through, 0.25, 1e-9);
  EXPECT_NEAR(wall.backed, 0.75, 1e-9);
  EXPECT_NEAR(wall.observed, 1.0, 1e-9);
  ASSERT_EQ(wall.seen_through_stretches.size(), 1u);
  EXPECT_NEAR(wall.seen_through_stretches[0].s0_m, 1.5, 1e-9);
  EXPECT_NEAR(wall.seen_through_stretches[0].s1_m, 2.5, 1e-9);
  for (std::size_t k = 1; k < 5; ++k) EXPECT_EQ(all[k].observed, 0.0);
}

TEST(PlanEvidenceTest, ShortUnknownGapsAreBridgedLongOnesAndOtherSamplesSplit) {
  const auto state = plan_state();
  // Seen through everywhere but two unknown samples at x ~ 1.0 (bridged), and a displaced stretch at 2.0-2.2 (not).
  const EdgeProbe probe = [](const Eigen::Vector2d& p, const Eigen::Vector2d&) {
    if (p.y() > 5) return EdgeSample::unknown;
    if (p.x() > 1.0 && p.x() < 1.1) return EdgeSample::unknown;
    if (p.x() > 2.0 && p.x() < 2.2) return EdgeSample::displaced;
    if (p.x() > 3.8) return EdgeSample::seen_through;  // 0.2 m alone: shorter than a stretch
    if (p.x() > 3.5) return EdgeSample::backed;
    return EdgeSample::seen_through;
  };
  const auto all = plan_evidence(state, probe, options());
  const auto& wall = all.at(0);
  ASSERT_EQ(wall.seen_through_stretches.size(), 2u);
  EXPECT_NEAR(wall.seen_through_stretches[0].s0_m, 0.0, 1e-9);
  EXPECT_NEAR(wall.seen_through_stretches[0].s1_m, 2.0, 1e-9);
  EXPECT_NEAR(wall.seen_through_stretches[1].s0_m, 2.2, 1e-9);
  EXPECT_NEAR(wall.seen_through_stretches[1].s1_m, 3.5, 1e-9);
  EXPECT_NEAR(wall.displaced, 0.05, 1e-9);
  EXPECT_NEAR(wall.observed, 1.0 - 0.025, 1e-9);
}

TEST(PlanEvidenceTest, ProbeLooksAcrossTheEdgeAtEverySample) {
  const auto state = plan_state();
  int calls = 0;
  const EdgeProbe probe = [&calls](const Eigen::Vector2d& p, const Eigen::Vector2d& normal) {
    ++calls;
    if (p.y() < 5) {
      EXPECT_NEAR(std::abs(normal.y()), 1.0, 1e-9);  // the wall runs along x
    }
    EXPECT_NEAR(normal.norm(), 1.0, 1e-9);
    return EdgeSample::unknown;
  };
  plan_evidence(state, probe, options());
  EXPECT_EQ(calls, 80 + 2 * 20 + 2 * 10);  // 4 m, 1 m and 0.5 m sides at 5 cm
}

TEST(PlanEvidenceTest, RegionLimitsTheEdgesLookedAt) {
  const auto state = plan_state();
  const EdgeProbe probe = [](const Eigen::Vector2d&, const Eigen::Vector2d&) { return EdgeSample::backed; };
  const auto near_table = plan_evidence(state, Box{9, 9, 11, 11}, probe, options());
  ASSERT_EQ(near_table.size(), 4u);
  for (const auto& e : near_table) EXPECT_EQ(e.object, 1u);
  EXPECT_TRUE(plan_evidence(state, Box{50, 50, 60, 60}, probe, options()).empty());
}

TEST(PlanEvidenceTest, EdgesFollowAMovedObject) {
  auto state = plan_state();
  auto table = state.objects[1];
  table.body = fusion::RigidObject({12, 10, 0}, table.body.pose_cov(), table.body.edges());
  state.objects.put(1, table);
  const EdgeProbe probe = [](const Eigen::Vector2d& p, const Eigen::Vector2d&) {
    return p.x() > 11 ? EdgeSample::backed : EdgeSample::seen_through;
  };
  for (const auto& e : plan_evidence(state, probe, options()))
    if (e.object == 1) {
      EXPECT_EQ(e.backed, 1.0);  // looked at where it stands now, not where it was drawn
    }
}

// A solid wall of one straight line from a to b.
apriori::PlanObject wall(std::string id, Eigen::Vector2d a, Eigen::Vector2d b) {
  apriori::PlanObject o;
  o.id = std::move(id);
  o.kind = "wall";
  o.attributes = {"solid"};
  o.polylines = {{a, b}};
  return o;
}

// Wall "w" from (0, 0) to (4, 0), met by "end" at its far end and by "tee" at x = 2, with "face" 5 cm beside it.
WorldState walls_meeting() {
  apriori::FloorPlan plan;
  plan.name = "junctions";
  plan.objects = {wall("w", {0, 0}, {4, 0}), wall("end", {4, -1}, {4, 1}), wall("tee", {2, 0}, {2, 2}),
                  wall("face", {0, 0.05}, {4, 0.05})};
  WorldState state;
  state.objects = ObjectTable(make_objects(plan, WorldOptions{}, 1));
  return state;
}

TEST(PlanEvidenceTest, WhereAnotherWallMeetsAnEdgeItTakesTheVerdictBesideIt) {
  const auto state = walls_meeting();
  // "w" is gone; the grid still shows the walls that meet it, where they meet it (x = 2 and x = 4).
  const auto gone = [](const Eigen::Vector2d& p, const Eigen::Vector2d&) {
    if (std::abs(p.y()) > 1e-9) return EdgeSample::unknown;
    return std::abs(p.x() - 4) < 0.1 || std::abs(p.x() - 2) < 0.1 ? EdgeSample::backed : EdgeSample::seen_through;
  };
  auto o = options();
  const auto found = plan_evidence(state, gone, o);
  ASSERT_FALSE(found.empty());
  EXPECT_EQ(found[0].object, 0u);
  EXPECT_NEAR(found[0].seen_through, 1.0, 1e-9);
  ASSERT_EQ(found[0].seen_through_stretches.size(), 1u);
  EXPECT_NEAR(found[0].seen_through_stretches[0].s0_m, 0.0, 1e-9);
  EXPECT_NEAR(found[0].seen_through_stretches[0].s1_m, 4.0, 1e-9);
  // A parallel face beside it is no junction: with only "face" near, the samples stay as probed.
  const auto face_only = [](const Eigen::Vector2d& p, const Eigen::Vector2d&) {
    if (std::abs(p.y()) > 1e-9) return EdgeSample::unknown;
    return p.x() < 1 ? EdgeSample::backed : EdgeSample::seen_through;
  };
  EXPECT_NEAR(plan_evidence(state, face_only, o)[0].backed, 0.25, 1e-9);
  // Where the samples beside a junction disagree (gone on one side, standing on the other), the probe stands.
  const auto half = [](const Eigen::Vector2d& p, const Eigen::Vector2d&) {
    if (std::abs(p.y()) > 1e-9) return EdgeSample::unknown;
    if (std::abs(p.x() - 2) < 0.1) return EdgeSample::displaced;
    return p.x() < 2 ? EdgeSample::seen_through : EdgeSample::backed;
  };
  const auto split = plan_evidence(state, half, o)[0];
  EXPECT_NEAR(split.displaced, 0.05, 1e-9);  // the 4 samples of x in (1.9, 2.1), two cells each side of the tee
  // Off: the junctions keep what the probe said.
  o.junction_cells = 0;
  EXPECT_NEAR(plan_evidence(state, gone, o)[0].seen_through, 0.925, 1e-9);
}

TEST(PlanEvidenceTest, AShortWallEndMostlyAtJunctionsKeepsWhatTheProbeSaid) {
  // The 30 cm end cap of a thick wall, met at both ends by the wall's long faces: 5 of its 6 samples lie within
  // 2.5 cells of a face, and the one between must not speak for all of them.
  apriori::FloorPlan plan;
  plan.name = "cap";
  plan.objects = {wall("cap", {0, 0}, {0.3, 0}), wall("left", {0, 0}, {0, 5}), wall("right", {0.3, 0}, {0.3, 5})};
  WorldState state;
  state.objects = ObjectTable(make_objects(plan, WorldOptions{}, 1));
  const auto middle_free = [](const Eigen::Vector2d& p, const Eigen::Vector2d&) {
    if (std::abs(p.y()) > 1e-9) return EdgeSample::unknown;
    return std::abs(p.x() - 0.15) < 0.03 ? EdgeSample::seen_through : EdgeSample::backed;
  };
  const auto found = plan_evidence(state, middle_free, options());
  ASSERT_FALSE(found.empty());
  EXPECT_EQ(found[0].object, 0u);
  EXPECT_LT(found[0].seen_through, 0.5);
  EXPECT_TRUE(found[0].seen_through_stretches.empty());
}

TEST(PlanEvidenceTest, UnknownSamplesThatManyBeamsCrossedAreSeenThrough) {
  const auto state = plan_state();
  // The probe sees through every other sample of the wall and leaves the rest unknown (too few misses on their
  // cells); the counted beams crossed x < 2 eight per 5 cm, none returning, and x >= 2 as often but half returned.
  const EdgeProbe striped = [](const Eigen::Vector2d& p, const Eigen::Vector2d&) {
    if (p.y() > 5) return EdgeSample::unknown;
    return static_cast<int>(std::floor(p.x() / 0.05)) % 2 == 0 ? EdgeSample::seen_through : EdgeSample::unknown;
  };
  int asked_elsewhere = 0;
  const EdgeCrossings crossings = [&](std::size_t object, std::size_t, double s0, double s1) {
    if (object != 0) {
      ++asked_elsewhere;
      return BeamTally{};
    }
    const auto beams = static_cast<std::int64_t>(std::lround((s1 - s0) / 0.05 * 8));
    return s0 < 2 ? BeamTally{beams, 0} : BeamTally{beams, beams / 2};
  };
  auto o = options();
  o.max_unknown_gap = 0;
  const auto wall = plan_evidence(state, striped, o, crossings).at(0);
  EXPECT_NEAR(wall.seen_through, 0.75, 1e-9);
  EXPECT_NEAR(wall.observed, 0.75, 1e-9);
  ASSERT_EQ(wall.seen_through_stretches.size(), 1u);  // x >= 2 stays split every other sample
  EXPECT_NEAR(wall.seen_through_stretches[0].s0_m, 0.0, 1e-9);
  EXPECT_NEAR(wall.seen_through_stretches[0].s1_m, 2.05, 1e-9);
  EXPECT_GT(asked_elsewhere, 0);  // the table's unseen sides were asked too, and stay unknown
  // Fewer beams than the option asks for: the probe alone.
  o.min_beams_crossing = 9;
  EXPECT_NEAR(plan_evidence(state, striped, o, crossings).at(0).seen_through, 0.5, 1e-9);
  o.min_beams_crossing = 0;
  EXPECT_NEAR(plan_evidence(state, striped, o, crossings).at(0).seen_through, 0.5, 1e-9);
  o.min_beams_crossing = -1;
  EXPECT_THROW(plan_evidence(state, striped, o, crossings), std::invalid_argument);
}

TEST(PlanEvidenceTest, BadOptionsAreRefused) {
  const auto state = plan_state();
  const EdgeProbe probe = [](const Eigen::Vector2d&, const Eigen::Vector2d&) { return EdgeSample::backed; };
  auto o = options();
  o.step_m = 0;
  EXPECT_THROW(plan_evidence(state, probe, o), std::invalid_argument);
  o.step_m = std::nan("");
  EXPECT_THROW(plan_evidence(state, probe, o), std::invalid_argument);
}

TEST(PlanEvidenceTest, ReportFindsEdgesByObjectAndEdge) {
  PlanReport report;
  report.edges.resize(3);
  report.edges[0].object = 0;
  report.edges[1].object = 2;
  report.edges[1].edge = 1;
  report.edges[2].object = 2;
  report.edges[2].edge = 3;
  EXPECT_EQ(report.find(2, 3), &report.edges[2]);
  EXPECT_EQ(report.find(2, 2), nullptr);
  EXPECT_EQ(report.find(0, 0), &report.edges[0]);
}

}  // namespace
}  // namespace wm::world
