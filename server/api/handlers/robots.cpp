// The robots the server has heard from: GET /api/v1/robots, GET /api/v1/robots/{id}, PUT /api/v1/robots/{id}/pose.
#include <chrono>

#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/request.h"
#include "server/api/response.h"
#include "server/json/robots_json.h"

namespace wm::api {
namespace {

double now_unix_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

nlohmann::json with_status(const Call& call, const service::RobotState& robot, double now) {
  const service::RobotRegistry rules(call.world.robots.robot_options());  // only for its status thresholds
  return json_codec::robot_json(robot, service::to_string(rules.status(robot, now)), now);
}

const std::string& robot_id(const Call& call) {
  if (!json_codec::valid_robot_id(call.param)) throw bad_request("id", "a robot id is 1 to 128 of A-Z a-z 0-9 . _ : -");
  return call.param;
}

}  // namespace

Response get_robots(const Call& call) {
  const double now = now_unix_s();
  nlohmann::json list = nlohmann::json::array();
  for (const auto& robot : call.world.robots.robots()) list.push_back(with_status(call, robot, now));
  const auto& options = call.world.robots.robot_options();
  return json_response(call.request, {{"robots", std::move(list)},
                                      {"alive_s", options.alive_s},
                                      {"status",
                                       "alive: heard from within alive_s; stale: silent longer; stopped: its last "
                                       "reported pose said so (until it sends again)"}});
}

Response get_robot(const Call& call) {
  const auto robot = call.world.robots.robot(robot_id(call));
  if (!robot)
    throw ApiError(404, "unknown_robot",
                   "no scan, primitives or pose came from '" + call.param + "'; GET /api/v1/robots lists the robots");
  return json_response(call.request, with_status(call, *robot, now_unix_s()));
}

Response put_robot_pose(const Call& call) {
  require_token(call.request, call.options);
  require_json_body(call.request);
  const auto& id = robot_id(call);
  auto reported = json_codec::parse_reported_pose(call.request.body());
  const auto robot = call.world.robots.put_robot_pose(id, std::move(reported.pose), reported.stopped);
  return json_response(call.request, with_status(call, robot, now_unix_s()));
}

}  // namespace wm::api
