// The robots the server has heard from: GET /api/v1/robots, GET /api/v1/robots/{id}, PUT /api/v1/robots/{id}/pose.
#include <chrono>
#include <map>
#include <string>
#include <vector>

#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/drive_relay.h"
#include "server/api/handlers.h"
#include "server/api/request.h"
#include "server/api/response.h"
#include "server/json/robots_json.h"

namespace wm::api {
namespace {

double now_unix_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// The robot with its status, and what the drive relay knows of it now: its telemetry (null when it reported none
// since wmd started) and its drive connections. A fault in the last telemetry makes the status "fault".
nlohmann::json with_status(const Call& call, const service::RobotState& robot, double now) {
  const service::RobotRegistry rules(call.world.robots.robot_options());  // only for its status thresholds
  auto j = json_codec::robot_json(robot, service::to_string(rules.status(robot, now)), now);
  if (call.drive) {
    bool fault = false;
    auto live = call.drive->robot_live(robot.id, fault);
    for (auto& [key, value] : live.items()) j[key] = std::move(value);
    if (fault) j["status"] = "fault";
  }
  return j;
}

const std::string& robot_id(const Call& call) {
  if (!json_codec::valid_robot_id(call.param)) throw bad_request("id", "a robot id is 1 to 128 of A-Z a-z 0-9 . _ : -");
  return call.param;
}

// Every robot of every map, once: on the map that heard from it last (a robot that took the lift has its track end on
// one floor and start on the next), with the maps that know it.
nlohmann::json robots_of_all_maps(const Call& call, double now) {
  struct Latest {
    service::RobotState robot;
    std::string map;
    std::vector<std::string> maps;
  };
  std::map<std::string, Latest> latest;
  const auto take = [&](const std::string& map, const std::vector<service::RobotState>& robots) {
    for (const auto& robot : robots) {
      auto [it, fresh] = latest.try_emplace(robot.id, Latest{robot, map, {}});
      it->second.maps.push_back(map);
      if (!fresh && robot.last_seen_unix_s > it->second.robot.last_seen_unix_s)
        it->second.robot = robot, it->second.map = map;
    }
  };
  take(std::string(call.map_id), call.world.robots.robots());
  for (const auto& id : call.maps->ids())
    if (const auto map = call.maps->find(id)) take(id, map->world.robots());
  nlohmann::json list = nlohmann::json::array();
  for (const auto& [id, entry] : latest) {
    auto robot = with_status(call, entry.robot, now);
    robot["map"] = entry.map;
    robot["maps"] = entry.maps;
    list.push_back(std::move(robot));
  }
  return list;
}

}  // namespace

Response get_robots(const Call& call) {
  const double now = now_unix_s();
  nlohmann::json list = nlohmann::json::array();
  if (call.maps && !call.map_scoped) {
    list = robots_of_all_maps(call, now);
  } else {
    for (const auto& robot : call.world.robots.robots()) {
      list.push_back(with_status(call, robot, now));
      list.back()["map"] = call.map_id;
    }
  }
  const auto& options = call.world.robots.robot_options();
  return json_response(call.request, {{"robots", std::move(list)},
                                      {"alive_s", options.alive_s},
                                      {"status",
                                       "alive: heard from within alive_s; stale: silent longer; stopped: its last "
                                       "reported pose said so (until it sends again); fault: its last telemetry "
                                       "reported a motor fault"}});
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
  if (reported.telemetry && call.drive) call.drive->put_telemetry(id, std::move(*reported.telemetry));
  return json_response(call.request, with_status(call, robot, now_unix_s()));
}

}  // namespace wm::api
