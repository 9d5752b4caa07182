// Plan registration with known answers: a 360° laser ray-cast inside the real GDC1 plan fills a Bayes grid, the
// plan is drawn displaced by a known similarity, and register_plan must find it again.
#include "fusion/registration/plan_registration.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

#include "fusion/grid/occupancy_grid.h"
#include "tests/support/test_data.h"
#include "tools/raycast/raycast.h"

namespace wm::fusion {
namespace {

using raycast::PlanLine;

constexpr double kDeg = std::numbers::pi / 180.0;

std::vector<PlanLine> gdc1() {
  return raycast::read_vectormap(
      testing::real_data("amrl-vectormaps/GDC1.vectormap.json", "plans/GDC1.vectormap.json").string());
}

ObservedMap observe(const std::vector<PlanLine>& lines) {
  OccupancyGrid grid(GridOptions{});
  for (const auto& scan : raycast::simulate_scans(lines, raycast::gdc1_route())) grid.insert(scan);
  const auto bounds = *grid.bounds();
  return {bounds, grid.export_layer(OccupancyGrid::Layer::bayes_probability, bounds), {}};
}

// The plan as an architect would have drawn it: the world lines taken back through the placement `truth`.
std::vector<DrawnEdge> drawn(const std::vector<PlanLine>& lines, const Similarity2D& truth) {
  std::vector<DrawnEdge> edges;
  for (const auto& l : lines)
    edges.push_back({truth.inverse_transform_point(l.p0), truth.inverse_transform_point(l.p1)});
  return edges;
}

class Gdc1Registration : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    lines_ = new std::vector<PlanLine>(gdc1());
    observed_ = new ObservedMap(observe(*lines_));
  }
  static void TearDownTestSuite() {
    delete observed_;
    delete lines_;
  }
  static void expect_placed(const RegistrationResult& r, const Similarity2D& truth) {
    EXPECT_NEAR(r.best.placement.x_m, truth.x_m, 0.05);
    EXPECT_NEAR(r.best.placement.y_m, truth.y_m, 0.05);
    EXPECT_NEAR(std::remainder(r.best.placement.theta_rad - truth.theta_rad, 2 * std::numbers::pi), 0.0, 0.5 * kDeg);
    EXPECT_NEAR(r.best.placement.scale / truth.scale, 1.0, 0.005);
    // Every drawn point lands within 5 cm of where it belongs.
    double worst = 0;
    for (const auto& l : *lines_)
      for (const auto& p : {l.p0, l.p1})
        worst = std::max(worst, (r.best.placement.transform_point(truth.inverse_transform_point(p)) - p).norm());
    EXPECT_LT(worst, 0.05);
  }
  static inline std::vector<PlanLine>* lines_ = nullptr;
  static inline ObservedMap* observed_ = nullptr;
};

TEST_F(Gdc1Registration, FindsAPlanDisplacedByUpToTenMetresAndHalfATurn) {
  for (const Similarity2D& truth :
       {Similarity2D{6.0, -7.5, 143 * kDeg, 1.0}, Similarity2D{-7.0, 6.5, 180 * kDeg, 1.0},
        Similarity2D{9.9, 0.5, -2.0 * kDeg, 1.0}, Similarity2D{0.3, -0.2, -91.0 * kDeg, 1.0}}) {
    SCOPED_TRACE("truth " + std::to_string(truth.x_m) + ", " + std::to_string(truth.y_m) + ", " +
                 std::to_string(truth.theta_rad / kDeg) + " deg");
    const auto edges = drawn(*lines_, truth);
    RegistrationOptions options;  // ±10 m, ±180°, scale 1, from the identity
    const auto r = register_plan(edges, *observed_, options);
    expect_placed(r, truth);
    EXPECT_FALSE(r.ambiguous);
    EXPECT_FALSE(r.timed_out);
    EXPECT_GT(r.best.score, 0.8);
    // A runner-up is reported when one reaches 0.7 of the best's search score; it must then be clearly worse.
    if (r.runner_up) {
      EXPECT_LT(r.runner_up->score * r.runner_up->coverage, 0.9 * r.best.score * r.best.coverage);
    }
    // The covariance is a real one: positive, and small for a plan that fits to millimetres.
    EXPECT_GT(r.covariance(0, 0), 0);
    EXPECT_LT(std::sqrt(r.covariance(0, 0)), 0.01);
    EXPECT_LT(std::sqrt(r.covariance(2, 2)), 0.001);
    EXPECT_LT(r.rms_m, 0.05);  // 5 cm cells: their centres lie up to 2.5 cm off the wall
  }
}

// The robots' frame turned against the plan's: the grid's walls are rasterised at those angles, which bends the
// directions read from them (a 5 × 5 window read a wall at 160° as 150° and the search missed it).
TEST(PlanRegistration, FindsThePlanWhateverTheHeadingOfTheRobotsFrame) {
  const auto lines = raycast::read_vectormap(
      testing::real_data("amrl-vectormaps/GDC1.vectormap.json", "plans/GDC1.vectormap.json").string());
  std::vector<DrawnEdge> edges;
  for (const auto& l : lines) edges.push_back({l.p0, l.p1});
  for (const Similarity2D& frame : {Similarity2D{6.0, -5.0, 160 * kDeg, 1.0}, Similarity2D{-3.0, 8.0, 33 * kDeg, 1.0},
                                    Similarity2D{2.0, 2.0, -109 * kDeg, 1.0}}) {
    SCOPED_TRACE("frame " + std::to_string(frame.theta_rad / kDeg) + " deg");
    std::vector<PlanLine> world;
    for (const auto& l : lines) world.push_back({frame.transform_point(l.p0), frame.transform_point(l.p1)});
    auto route = raycast::gdc1_route();
    for (auto& polyline : route)
      for (auto& p : polyline) p = frame.transform_point(p);
    OccupancyGrid grid(GridOptions{});
    for (const auto& scan : raycast::simulate_scans(world, route)) grid.insert(scan);
    const auto bounds = *grid.bounds();
    const ObservedMap observed{bounds, grid.export_layer(OccupancyGrid::Layer::bayes_probability, bounds), {}};
    const auto r = register_plan(edges, observed, {});
    double worst = 0;
    for (const auto& l : lines)
      worst = std::max(worst, (r.best.placement.transform_point(l.p0) - frame.transform_point(l.p0)).norm());
    EXPECT_LT(worst, 0.05);
    EXPECT_NEAR(std::remainder(r.best.placement.theta_rad - frame.theta_rad, 2 * std::numbers::pi), 0.0, 0.5 * kDeg);
    EXPECT_FALSE(r.ambiguous);
  }
}

TEST_F(Gdc1Registration, FindsAThousandfoldUnitErrorAmongTheUnitCandidates) {
  const Similarity2D truth{3.0, -2.0, 30 * kDeg, 0.001};  // drawn in millimetres, read as metres
  const auto edges = drawn(*lines_, truth);
  RegistrationOptions options;
  options.scale_candidates = {1.0, 0.01, 0.001, 0.0254, 0.3048};
  const auto r = register_plan(edges, *observed_, options);
  expect_placed(r, truth);
  EXPECT_GT(r.covariance(3, 3), 0);
}

TEST_F(Gdc1Registration, RefinesAScaleErrorWithinARange) {
  const Similarity2D truth{-1.0, 2.0, 10 * kDeg, 1.02};
  const auto edges = drawn(*lines_, truth);
  RegistrationOptions options;
  options.scale_min = 0.97;
  options.scale_max = 1.03;
  options.max_rotation_rad = 20 * kDeg;
  const auto r = register_plan(edges, *observed_, options);
  expect_placed(r, truth);
}

TEST_F(Gdc1Registration, APlanOfAnotherBuildingScoresLow) {
  const auto other = raycast::read_vectormap(
      testing::real_data("amrl-vectormaps/AHG2.vectormap.json", "plans/AHG2.vectormap.json").string());
  std::vector<DrawnEdge> edges;
  // Centred on GDC1's area, so the search looks where the robots were.
  for (const auto& l : other) edges.push_back({l.p0 - Eigen::Vector2d(40, 50), l.p1 - Eigen::Vector2d(40, 50)});
  const auto r = register_plan(edges, *observed_, {});
  EXPECT_LT(r.best.score, 0.5) << "coverage " << r.best.coverage;
}

// The threads prune with each other's best leaf in an order no run repeats; ties are broken by a fixed order, so the
// placement, its scores and the runner-up must not depend on their number.
TEST_F(Gdc1Registration, FindsTheSamePlacementOnOneThreadAndOnMany) {
  const Similarity2D truth{6.0, -7.5, 143 * kDeg, 1.0};
  const auto edges = drawn(*lines_, truth);
  RegistrationOptions options;
  options.threads = 1;
  const auto one = register_plan(edges, *observed_, options);
  expect_placed(one, truth);
  for (const unsigned threads : {2u, 3u, 8u}) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    options.threads = threads;
    const auto many = register_plan(edges, *observed_, options);
    EXPECT_EQ(many.best.placement.x_m, one.best.placement.x_m);
    EXPECT_EQ(many.best.placement.y_m, one.best.placement.y_m);
    EXPECT_EQ(many.best.placement.theta_rad, one.best.placement.theta_rad);
    EXPECT_EQ(many.best.placement.scale, one.best.placement.scale);
    EXPECT_EQ(many.best.score, one.best.score);
    EXPECT_EQ(many.search_score, one.search_score);
    ASSERT_EQ(many.runner_up.has_value(), one.runner_up.has_value());
    if (one.runner_up) {
      EXPECT_EQ(many.runner_up->placement.x_m, one.runner_up->placement.x_m);
      EXPECT_EQ(many.runner_up->placement.theta_rad, one.runner_up->placement.theta_rad);
    }
  }
}

// Walls drawn exactly where the raster has them: many windows bound the best leaf's score exactly, the case where
// which thread finds a tie first would decide without the fixed order.
TEST(PlanRegistration, BreaksTiesOfAnExactFitTheSameWayOnAnyNumberOfThreads) {
  std::vector<DrawnEdge> world;
  for (int row = 0; row < 3; ++row)
    for (int k = 0; k < 6; ++k) {
      const double x = 4.2 * k, y = 6.0 * row, w = 4.0, d = 4.0;
      const Eigen::Vector2d a(x, y), b(x + w, y), c(x + w, y + d), e(x, y + d);
      world.insert(world.end(), {{a, b}, {b, c}, {c, e}, {e, a}});
    }
  const GridGeometry g({-1, -1}, 0.05, 540, 380);
  std::vector<float> p(static_cast<std::size_t>(g.width() * g.height()), 0.2f);
  for (const auto& l : world)
    for (int i = 0; i <= 400; ++i) {
      const auto cell = g.cell_of(l.p0 + (l.p1 - l.p0) * (i / 400.0));
      p[static_cast<std::size_t>(cell.y * g.width() + cell.x)] = 0.9f;
    }
  const ObservedMap observed{g, std::move(p), {}};
  const Similarity2D truth{2.0, -1.5, 0.4, 1.0};
  std::vector<DrawnEdge> edges;
  for (const auto& l : world)
    edges.push_back({truth.inverse_transform_point(l.p0), truth.inverse_transform_point(l.p1)});
  RegistrationOptions options;
  options.threads = 1;
  const auto one = register_plan(edges, observed, options);
  EXPECT_NEAR(one.best.placement.x_m, truth.x_m, 0.05);  // one cell: the raster is of 5 cm
  EXPECT_NEAR(one.best.placement.y_m, truth.y_m, 0.05);
  EXPECT_GT(one.best.score, 0.95);
  for (const unsigned threads : {2u, 4u, 7u}) {
    options.threads = threads;
    const auto many = register_plan(edges, observed, options);
    EXPECT_EQ(many.best.placement.x_m, one.best.placement.x_m) << threads << " threads";
    EXPECT_EQ(many.best.placement.y_m, one.best.placement.y_m) << threads << " threads";
    EXPECT_EQ(many.best.placement.theta_rad, one.best.placement.theta_rad) << threads << " threads";
    EXPECT_EQ(many.search_score, one.search_score) << threads << " threads";
  }
}

TEST(PlanRegistration, ARoomWithAHalfTurnSymmetryIsAmbiguous) {
  // Two equal rooms side by side along a corridor, point-symmetric about the origin.
  std::vector<PlanLine> lines;
  const auto box = [&](double x0, double y0, double x1, double y1) {
    lines.push_back({{x0, y0}, {x1, y0}});
    lines.push_back({{x1, y0}, {x1, y1}});
    lines.push_back({{x1, y1}, {x0, y1}});
    lines.push_back({{x0, y1}, {x0, y0}});
  };
  box(-12, -4, 12, 4);
  lines.push_back({{-12, 1}, {-3, 1}});  // a wall at one side ...
  lines.push_back({{12, -1}, {3, -1}});  // ... and its twin turned by half a turn
  OccupancyGrid grid(GridOptions{});
  for (const auto& scan : raycast::simulate_scans(lines, {{{-10, -2.5}, {10, -2.5}}, {{10, 2.5}, {-10, 2.5}}}))
    grid.insert(scan);
  const auto bounds = *grid.bounds();
  const ObservedMap observed{bounds, grid.export_layer(OccupancyGrid::Layer::bayes_probability, bounds), {}};
  const Similarity2D truth{1.0, 0.5, 20 * kDeg, 1.0};
  std::vector<DrawnEdge> edges;
  for (const auto& l : lines)
    edges.push_back({truth.inverse_transform_point(l.p0), truth.inverse_transform_point(l.p1)});
  const auto r = register_plan(edges, observed, {});
  EXPECT_TRUE(r.ambiguous);
  ASSERT_TRUE(r.runner_up.has_value());
  const double turn =
      std::remainder(r.runner_up->placement.theta_rad - r.best.placement.theta_rad, 2 * std::numbers::pi);
  EXPECT_NEAR(std::abs(turn), std::numbers::pi, 2 * kDeg);
}

TEST(PlanRegistration, RefusesWhatItCannotPlace) {
  const GridGeometry g({0, 0}, 0.05, 10, 10);
  const ObservedMap empty{g, std::vector<float>(100, 0.2f), {}};
  const std::vector<DrawnEdge> edge{{{0, 0}, {1, 0}}};
  EXPECT_THROW(register_plan({}, empty, {}), RegistrationError);
  EXPECT_THROW(register_plan(edge, empty, {}), RegistrationError);  // no occupied cell
  ObservedMap one = empty;
  one.probability[55] = 0.9f;
  RegistrationOptions bad;
  bad.scale_min = 2;
  bad.scale_max = 1;
  EXPECT_THROW(register_plan(edge, one, bad), RegistrationError);
  bad = {};
  bad.threads = 0;
  EXPECT_THROW(register_plan(edge, one, bad), RegistrationError);
  bad = {};
  bad.max_translation_m = std::nan("");
  EXPECT_THROW(register_plan(edge, one, bad), RegistrationError);
  bad = {};
  bad.scale_min = 0.001;
  bad.scale_max = 1000;
  EXPECT_THROW(register_plan(std::vector<DrawnEdge>{{{0, 0}, {100, 0}}}, one, bad), RegistrationError);
  // Bounds that would take millions of windows are refused before anything is allocated for them.
  bad = {};
  bad.max_translation_m = 1000;
  try {
    register_plan(std::vector<DrawnEdge>{{{0, 0}, {100, 0}}}, one, bad);
    ADD_FAILURE() << "a search of 77 million windows must be refused";
  } catch (const RegistrationError& e) {
    EXPECT_NE(std::string(e.what()).find("narrow max_translation"), std::string::npos) << e.what();
  }
}

TEST(PlacementFromPairs, RecoversASimilarityAndRefusesDegeneratePairs) {
  const Similarity2D truth{12.0, -3.0, 0.7, 0.001};
  std::vector<PointPair> pairs;
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(1000, 2000), Eigen::Vector2d(-5000, 300), Eigen::Vector2d(250, -7000)})
    pairs.push_back({p, truth.transform_point(p)});
  const auto placed = place_from_pairs(pairs, true);
  EXPECT_NEAR(placed.placement.x_m, truth.x_m, 1e-9);
  EXPECT_NEAR(placed.placement.y_m, truth.y_m, 1e-9);
  EXPECT_NEAR(placed.placement.theta_rad, truth.theta_rad, 1e-12);
  EXPECT_NEAR(placed.placement.scale, truth.scale, 1e-12);
  EXPECT_LT(placed.rms_m, 1e-9);
  // Known to the pick error: σ of x is of the order of 5 cm, not zero.
  EXPECT_GT(std::sqrt(placed.covariance(0, 0)), 0.01);
  EXPECT_LT(std::sqrt(placed.covariance(0, 0)), 0.2);
  // Without scale the drawing keeps its size.
  EXPECT_DOUBLE_EQ(place_from_pairs(pairs, false).placement.scale, 1.0);

  EXPECT_THROW(place_from_pairs({pairs[0]}, false), RegistrationError);
  EXPECT_THROW(place_from_pairs({pairs[0], pairs[0]}, false), RegistrationError);
  auto nan = pairs;
  nan[1].world.x() = std::nan("");
  EXPECT_THROW(place_from_pairs(nan, false), RegistrationError);
}

}  // namespace
}  // namespace wm::fusion
