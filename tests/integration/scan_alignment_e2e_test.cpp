// Scans aligned to the map through the running wmd: a scan posted off its true pose is placed nearer to it and says
// so in its answer; a pose covariance that is not one is refused and changes nothing; an exact pose, a guess and a
// scan that sees no line keep the pose posted; the server keeps serving.
#include <chrono>
#include <cmath>
#include <numbers>

#include "grid_room.h"

namespace wm::testing {
namespace {

using grid_room::GridTest;
using grid_room::room_scan;

constexpr double kDeg = std::numbers::pi / 180;

json with_cov(json scan, double sigma_xy_m, double sigma_theta_rad) {
  const double vxy = sigma_xy_m * sigma_xy_m, vth = sigma_theta_rad * sigma_theta_rad;
  scan["pose_cov"] = {{vxy, 0, 0}, {0, vxy, 0}, {0, 0, vth}};
  return scan;
}

// The scan taken at `truth`, posted as if the robot believed it stood at truth + (dx, dy, dθ).
json posted_off(double x, double y, double theta, double dx, double dy, double dtheta) {
  json scan = room_scan(x, y, theta);
  scan["pose"] = {{"x", x + dx}, {"y", y + dy}, {"theta", theta + dtheta}};
  return scan;
}

class ScanAlignmentTest : public GridTest {
 protected:
  // The room mapped from four poses known to σ 1 cm / 0.2°.
  void map_the_room() {
    for (const auto& [x, y, theta] :
         {std::tuple{2.0, 2.0, 0.0}, std::tuple{5.0, 3.0, 1.0}, std::tuple{3.0, 4.0, -0.5}, std::tuple{6.0, 2.0, 2.0}})
      post_scan(with_cov(room_scan(x, y, theta), 0.01, 0.2 * kDeg));
  }
};

TEST_F(ScanAlignmentTest, AScanPostedOffItsPoseIsPlacedNearerToItAndSaysWhere) {
  map_the_room();
  const double x = 4.0, y = 3.0, theta = 0.3, dx = 0.06, dy = -0.05, dtheta = 1.0 * kDeg;
  const auto answer = post_scan(with_cov(posted_off(x, y, theta, dx, dy, dtheta), 0.03, 0.5 * kDeg));
  const auto& pose = answer["pose"];
  ASSERT_TRUE(pose.is_object()) << answer.dump();
  EXPECT_EQ(pose["aligned"], true);
  // The map knows the room far better than this pose: most of the error is taken out.
  const double error_before = std::hypot(dx, dy);
  const double error_after = std::hypot(pose["x"].get<double>() - x, pose["y"].get<double>() - y);
  EXPECT_LT(error_after, 0.4 * error_before) << pose.dump();
  // Directions: an element's is known no better than the 0.5° floor of its covariance (the error poses share), as
  // this pose's is, so the heading goes about half way.
  EXPECT_LT(std::abs(pose["theta"].get<double>() - theta), 0.6 * dtheta) << pose.dump();
  EXPECT_NEAR(pose["dx"].get<double>(), pose["x"].get<double>() - (x + dx), 1e-12);
  EXPECT_NEAR(pose["dtheta"].get<double>(), pose["theta"].get<double>() - (theta + dtheta), 1e-12);
  // The robot stands where its scan was placed.
  const auto robot = get_json("/api/v1/robots/robot-1");
  EXPECT_EQ(robot["pose"]["x"], pose["x"]);
  EXPECT_EQ(robot["pose"]["theta"], pose["theta"]);
  // Placed right, the scan confirmed the room's walls and added none beside them.
  EXPECT_EQ(get_json("/api/v1/map")["elements"].size(), 4u);
}

TEST_F(ScanAlignmentTest, WithoutTheOptionEveryScanKeepsItsPostedPose) {
  extra_args_.push_back("--no-scan-alignment");
  restart();
  map_the_room();
  const auto answer = post_scan(with_cov(posted_off(4.0, 3.0, 0.3, 0.06, -0.05, 1.0 * kDeg), 0.03, 0.5 * kDeg));
  EXPECT_EQ(answer["pose"]["aligned"], false);
  EXPECT_EQ(answer["pose"]["dx"], 0.0);
  EXPECT_EQ(answer["pose"]["x"], 4.06);
}

TEST_F(ScanAlignmentTest, HostilePoseCovariancesAreRefusedOrLeaveThePoseAsPostedAndTheServerKeepsServing) {
  map_the_room();
  const std::string map_before = get_raw("/api/v1/map");
  const auto scan = posted_off(4.0, 3.0, 0.3, 0.06, -0.05, 1.0 * kDeg);
  // Not a covariance: refused whole at the edge, nothing journaled or decided.
  for (const json& bad :
       {json{{1e-3, 2e-3, 0}, {2e-3, 1e-3, 0}, {0, 0, 1e-4}}, json{{1e-3, 0, 0}, {0, -1e-3, 0}, {0, 0, 1e-4}},
        json{{1e-3, 1e-4, 0}, {0, 1e-3, 0}, {0, 0, 1e-4}}, json{{1e-3, 0}, {0, 1e-3}}, json{{"x", 1}},
        json{{1e-3, 0, 0}, {0, 1e-3, 0}, {0, 0, "wide"}}}) {
    auto body = scan;
    body["pose_cov"] = bad;
    const auto r = call("POST", "/api/v1/scans", body.dump());
    EXPECT_EQ(r.status, 400) << bad.dump() << ": " << r.body;
    EXPECT_NE(r.body.find("pose_cov"), std::string::npos) << r.body;
  }
  EXPECT_EQ(get_raw("/api/v1/map"), map_before);
  EXPECT_EQ(get_json("/api/v1/robots/robot-1")["scans"]["laser"], 4);

  // An exact pose (zero covariance), a guess (σ 100 m, 3 rad) and the largest variance the codec takes: kept as
  // posted, answered at once.
  for (const auto& [sxy, sth] : {std::pair{0.0, 0.0}, std::pair{100.0, 3.0}, std::pair{1000.0, 1000.0}}) {
    const auto start = std::chrono::steady_clock::now();
    const auto answer = post_scan(with_cov(scan, sxy, sth));
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
    EXPECT_EQ(answer["pose"]["aligned"], false) << sxy;
    EXPECT_EQ(answer["pose"]["x"], 4.06) << sxy;
  }
  // A scan that sees no line (every beam without a return) has nothing to align and keeps its pose.
  auto empty = with_cov(scan, 0.03, 0.5 * kDeg);
  for (auto& r : empty["ranges"]) r = 20.0;
  const auto answer = post_scan(empty);
  EXPECT_EQ(answer["pose"]["aligned"], false);
  EXPECT_EQ(answer["lines"], nullptr);
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
}

}  // namespace
}  // namespace wm::testing
