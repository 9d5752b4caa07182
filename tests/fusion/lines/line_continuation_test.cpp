// continue_line: a known wall followed past its end through the sparse returns of a grazing view (stepping over the
// returns the extractor claimed), and stopped where the beams say the wall is not there (an opening, nothing
// returned), where something hides it and at a return on a neighbour's line; returns bunched at a corner are no
// continuation. Scans are ray-cast against lines (tools/raycast).
#include "fusion/lines/line_continuation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

#include "tools/raycast/raycast.h"

namespace wm::fusion {
namespace {

constexpr double kStep = 0.5 * std::numbers::pi / 180;  // a 0.5° laser

// A 360° scan from the origin against `lines`, every beam's return (+inf: none within 20 m), with range noise.
std::vector<ContinuationBeam> scan(const std::vector<raycast::PlanLine>& lines, double sigma_m = 0.0,
                                   unsigned seed = 1) {
  std::mt19937 random(seed);
  std::normal_distribution<double> noise(0.0, sigma_m > 0 ? sigma_m : 1.0);
  std::vector<ContinuationBeam> beams;
  for (int i = 0; i < 720; ++i) {
    const double bearing = -std::numbers::pi + i * kStep;
    double r = raycast::cast_ray(lines, Eigen::Vector2d::Zero(), {std::cos(bearing), std::sin(bearing)}, 20.0);
    if (std::isfinite(r) && sigma_m > 0) r += noise(random);
    beams.push_back(ContinuationBeam::at(bearing, r));
  }
  return beams;
}

LineContinuationOptions options() {
  LineContinuationOptions o;
  o.bearing_step_rad = kStep;
  return o;
}

// The wall y = 1.5 known from x = −1 to x = 6, where the laser at the origin meets it at 14°: farther out it sees
// the wall at a grazing angle, its returns 0.39 m apart at x = 8, 0.72 m at x = 11.
LineSegment known_wall(double end_x = 6.0, double y = 1.5) {
  return LineSegment::from_points({-1.0, y}, {end_x, y}, Eigen::Vector2d(1e-4, 1e-6).asDiagonal());
}

// The continuation past the known end toward +x, as its two ends ordered by x (NaN: none).
std::pair<Eigen::Vector2d, Eigen::Vector2d> past_end(const std::vector<ContinuationBeam>& beams,
                                                     const LineContinuationOptions& o = options(),
                                                     const LineSegment& known = known_wall()) {
  const bool beyond_t1 = known.p1().x() > known.p0().x();
  const auto c = continue_line(beams, known, beyond_t1, o);
  if (!c) return {Eigen::Vector2d::Constant(NAN), Eigen::Vector2d::Constant(NAN)};
  return c->p0().x() < c->p1().x() ? std::pair{c->p0(), c->p1()} : std::pair{c->p1(), c->p0()};
}

TEST(LineContinuationTest, FollowsAGrazingWallOutToItsEndOnItsLine) {
  const auto [near, far] = past_end(scan({{{-1, 1.5}, {12, 1.5}}}, 0.01));
  ASSERT_TRUE(std::isfinite(near.x()));
  EXPECT_NEAR(near.x(), 6.0, 0.01);  // from the known end...
  EXPECT_GT(far.x(), 11.0);          // ...to the last return before the wall's end at 12 m
  EXPECT_LE(far.x(), 12.01);
  EXPECT_NEAR(near.y(), 1.5, 0.01);
  EXPECT_NEAR(far.y(), 1.5, 0.02);
}

TEST(LineContinuationTest, StopsAtAnOpeningTheBeamsGoThrough) {
  // An opening from x = 9 to 9.6, a wall 1 m behind it: the beams through it return from behind the line.
  const auto [near, far] = past_end(scan({{{-1, 1.5}, {9, 1.5}}, {{9.6, 1.5}, {14, 1.5}}, {{0, 2.5}, {14, 2.5}}}));
  ASSERT_TRUE(std::isfinite(far.x()));
  EXPECT_LE(far.x(), 9.0);
  EXPECT_GT(far.x(), 8.5);
  // Nothing behind the opening (no return within range): the same.
  const auto [near2, far2] = past_end(scan({{{-1, 1.5}, {9, 1.5}}, {{9.6, 1.5}, {14, 1.5}}}));
  EXPECT_LE(far2.x(), 9.0);
  EXPECT_GT(far2.x(), 8.5);
}

TEST(LineContinuationTest, StopsWhereSomethingInFrontHidesTheWall) {
  // A board between sensor and wall at y = 1.2 hides the wall from x = 10 on.
  const auto [near, far] = past_end(scan({{{-1, 1.5}, {14, 1.5}}, {{8, 1.2}, {9, 1.2}}}));
  ASSERT_TRUE(std::isfinite(far.x()));
  EXPECT_LT(far.x(), 10.0);
  EXPECT_GT(far.x(), 9.0);
}

TEST(LineContinuationTest, StepsOverTheReturnsTheExtractorClaimedWithoutTakingThem) {
  // Returns past x = 9 claimed: they are the extractor's line's, so the continuation's evidence ends before them.
  auto beams = scan({{{-1, 1.5}, {12, 1.5}}});
  const auto x_of = [](const ContinuationBeam& b) { return b.range_m * b.direction.x(); };
  for (auto& b : beams) b.claimed = std::isfinite(b.range_m) && b.direction.y() > 0 && x_of(b) > 9.0;
  const auto [near, far] = past_end(beams);
  ASSERT_TRUE(std::isfinite(far.x()));
  EXPECT_LE(far.x(), 9.0);
  EXPECT_GT(far.x(), 8.5);
  // The wall known only to x = 1, the scan's own line taking it from there to x = 7, steep returns all: the
  // continuation steps over them to the grazing part.
  for (auto& b : beams) b.claimed = std::isfinite(b.range_m) && b.direction.y() > 0 && x_of(b) <= 7.0;
  EXPECT_GT(past_end(beams, options(), known_wall(1.0)).second.x(), 11.0);
  // All of them claimed: no evidence of its own, no continuation.
  for (auto& b : beams) b.claimed = std::isfinite(b.range_m);
  EXPECT_FALSE(std::isfinite(past_end(beams).second.x()));
}

TEST(LineContinuationTest, ReturnsBunchedAtACornerAreNoContinuation) {
  // The wall ends at x = 6.1 in a crossing wall running away from the sensor: past the end, the beams return from the
  // crossing wall behind the line, and the few on the line lie within 10 cm of the end.
  const auto [near, far] = past_end(scan({{{-1, 1.5}, {6.1, 1.5}}, {{6.1, 1.5}, {6.1, 6}}}));
  EXPECT_FALSE(std::isfinite(far.x()));
}

TEST(LineContinuationTest, ReturnsSeenAtASteepAngleAreTheExtractorsNotAContinuation) {
  // Known to x = 1, the wall on to 12 m: past the end the laser meets it at 56° to 15°, and those returns, left
  // alone by the extractor here, are no continuation; from x = 6 on (14°) they are.
  EXPECT_FALSE(std::isfinite(past_end(scan({{{-1, 1.5}, {12, 1.5}}}), options(), known_wall(1.0)).second.x()));
  auto o = options();
  o.max_incidence_rad = 1.5;
  EXPECT_GT(past_end(scan({{{-1, 1.5}, {12, 1.5}}}), o, known_wall(1.0)).second.x(), 11.0);
}

TEST(LineContinuationTest, TooFewReturnsOrTooShortAStretchIsNone) {
  auto o = options();
  o.min_points = 1000;
  EXPECT_FALSE(std::isfinite(past_end(scan({{{-1, 1.5}, {12, 1.5}}}), o).second.x()));
  o = options();
  o.min_length_m = 50;
  EXPECT_FALSE(std::isfinite(past_end(scan({{{-1, 1.5}, {12, 1.5}}}), o).second.x()));
}

TEST(LineContinuationTest, AContinuationIsTheKnownLineCarriedOnNotALineOfItsOwn) {
  // The known line lies 5 mm off the wall and the returns scatter by 5 mm: the continuation is the known line itself
  // (a continuation says how far the line runs), from its end to the farthest return taken.
  const auto known = known_wall(6.0, 1.505);
  const bool beyond_t1 = known.p1().x() > known.p0().x();
  const auto c = continue_line(scan({{{-1, 1.5}, {12, 1.5}}}, 0.005, 3), known, beyond_t1, options());
  ASSERT_TRUE(c);
  EXPECT_EQ(c->line.rho_m, known.line.rho_m);
  EXPECT_EQ(c->line.phi_rad, known.line.phi_rad);
  EXPECT_EQ(c->line.cov, known.line.cov);
  EXPECT_DOUBLE_EQ(beyond_t1 ? c->t0_m : c->t1_m, beyond_t1 ? known.t1_m : known.t0_m);
  EXPECT_GT(c->length_m(), 5.0);  // out to x > 11
}

TEST(LineContinuationTest, StopsAtAReturnOnANeighboursLine) {
  // Returns past x = 9 lie on another line of the map (a neighbouring facet): the continuation ends before them.
  const auto beams = scan({{{-1, 1.5}, {12, 1.5}}});
  std::size_t asked = 0;
  const ForeignReturn past_9 = [&](std::size_t i) {
    ++asked;
    return beams[i].range_m * beams[i].direction.x() > 9.0;
  };
  const auto known = known_wall();
  const auto c = continue_line(beams, known, known.p1().x() > known.p0().x(), options(), past_9);
  ASSERT_TRUE(c);
  EXPECT_LE(std::max(c->p0().x(), c->p1().x()), 9.0);
  EXPECT_GT(std::max(c->p0().x(), c->p1().x()), 8.5);
  EXPECT_LT(asked, 40u);  // asked of the returns walked, not of the scan's 720
}

TEST(LineContinuationTest, ALineNeverGrazedWithinRangeGivesNone) {
  // 6 m off: within 20 m the laser meets it at 17° or more.
  const auto known = LineSegment::from_points({-1.0, 6.0}, {6.0, 6.0}, Eigen::Vector2d(1e-4, 1e-6).asDiagonal());
  EXPECT_FALSE(continue_line(scan({{{-1, 6.0}, {30, 6.0}}}), known, known.p1().x() > known.p0().x(), options()));
}

TEST(LineContinuationTest, RefusesBadInput) {
  auto beams = scan({{{-1, 1.5}, {12, 1.5}}});
  auto o = options();
  o.min_offset_m = 0;
  EXPECT_THROW(continue_line(beams, known_wall(), true, o), std::invalid_argument);
  o = options();
  o.max_spacing_m = std::numeric_limits<double>::infinity();
  EXPECT_THROW(continue_line(beams, known_wall(), true, o), std::invalid_argument);
  beams[3].bearing_rad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(continue_line(beams, known_wall(), true, options()), std::invalid_argument);
  beams = scan({{{-1, 1.5}, {12, 1.5}}});
  for (auto& b : beams) b.direction.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(continue_line(beams, known_wall(), true, options()), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
