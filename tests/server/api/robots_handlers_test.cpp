// The robots routes against the fake port's registry: listing, one robot, reported poses and their refusals.
#include "tests/server/api/api_test_helpers.h"

namespace wm::testing {
namespace {

class RobotsHandlersTest : public ApiTest {};

TEST_F(RobotsHandlersTest, AReportedPoseIsAnsweredListedAndShownAlive) {
  EXPECT_EQ(json_of(send(http::verb::get, "/api/v1/robots"))["robots"].size(), 0u);
  const auto put = send(http::verb::put, "/api/v1/robots/robot-1/pose",
                        R"({"x": 1.5, "y": -2, "theta": 0.25, "cov": [[0.01, 0, 0], [0, 0.01, 0], [0, 0, 0.001]],
                            "stamp": 12.5})");
  ASSERT_EQ(status_of(put), 200) << put.body();
  const auto robot = json_of(put);
  EXPECT_EQ(robot["id"], "robot-1");
  EXPECT_EQ(robot["status"], "alive");
  EXPECT_DOUBLE_EQ(robot["pose"]["x"].get<double>(), 1.5);
  EXPECT_DOUBLE_EQ(robot["pose"]["theta"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(robot["pose"]["cov"][2][2].get<double>(), 0.001);
  EXPECT_EQ(robot["pose"]["via"], "reported");
  EXPECT_EQ(robot["pose"]["source"], "reported");  // the older name, still there
  EXPECT_EQ(robot["poses"], 1);
  EXPECT_EQ(robot["sensors"], nlohmann::json::array({"pose"}));
  EXPECT_EQ(world_.calls.back(), "put_robot_pose");

  const auto listed = json_of(send(http::verb::get, "/api/v1/robots"));
  ASSERT_EQ(listed["robots"].size(), 1u);
  EXPECT_EQ(listed["robots"][0]["id"], "robot-1");
  EXPECT_DOUBLE_EQ(listed["alive_s"].get<double>(), 5.0);
  EXPECT_EQ(json_of(send(http::verb::get, "/api/v1/robots/robot-1"))["pose"]["y"], -2.0);

  const auto stopped = json_of(send(http::verb::put, "/api/v1/robots/robot-1/pose",
                                    R"({"x": 1.5, "y": -2, "theta": 0.25, "state": "stopped"})"));
  EXPECT_EQ(stopped["status"], "stopped");
  EXPECT_EQ(stopped["track"].size(), 1u) << "the same place twice is one track point";
}

TEST_F(RobotsHandlersTest, BadPosesAndIdsAreRefusedWithTheReasonAndChangeNothing) {
  const std::pair<const char*, const char*> bad[] = {
      {R"({"y": 0, "theta": 0})", "x: missing"},
      {R"({"x": "1", "y": 0, "theta": 0})", "x: expected a number"},
      {R"({"x": 1e6, "y": 0, "theta": 0})", "x: absurd value"},
      {R"({"x": 0, "y": 0, "theta": 0, "cov": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]})", "cov: not symmetric"},
      {R"({"x": 0, "y": 0, "theta": 0, "cov": [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]})", "cov: a variance is negative"},
      {R"({"x": 0, "y": 0, "theta": 0, "cov": [[1, 2, 0], [2, 1, 0], [0, 0, 1]]})", "cov: not positive semi-definite"},
      {R"({"x": 0, "y": 0, "theta": 0, "cov": [[1, 0], [0, 1]]})", "cov: expected a 3×3"},
      {R"({"x": 0, "y": 0, "theta": 0, "state": "flying"})", "state: expected"},
      {R"({"x": 0, "y": 0, "theta": 0, "speed": 1})", "speed: unknown field"},
      {R"([1, 2, 3])", "expected an object"},
      {R"({"x": 0,)", "malformed JSON"},
  };
  for (const auto& [body, reason] : bad) {
    const auto answer = send(http::verb::put, "/api/v1/robots/r2/pose", body);
    EXPECT_EQ(status_of(answer), 400) << body;
    EXPECT_NE(json_of(answer)["detail"].get<std::string>().find(reason), std::string::npos)
        << body << " → " << answer.body();
  }
  EXPECT_EQ(status_of(send(http::verb::put, "/api/v1/robots/a%20b/pose", R"({"x": 0, "y": 0, "theta": 0})")), 400);
  EXPECT_EQ(status_of(send(http::verb::get, "/api/v1/robots/r2")), 404);
  EXPECT_EQ(json_of(send(http::verb::get, "/api/v1/robots"))["robots"].size(), 0u) << "nothing was applied";
}

TEST_F(RobotsHandlersTest, AReportedPoseNeedsTheTokenWhenOneIsConfigured) {
  options_.token = "s3cret";
  EXPECT_EQ(status_of(send(http::verb::put, "/api/v1/robots/r1/pose", R"({"x": 0, "y": 0, "theta": 0})")), 401);
  auto request = make_request(http::verb::put, "/api/v1/robots/r1/pose", R"({"x": 0, "y": 0, "theta": 0})");
  request.set(http::field::authorization, "Bearer s3cret");
  EXPECT_EQ(status_of(send(request)), 200);
}

}  // namespace
}  // namespace wm::testing
