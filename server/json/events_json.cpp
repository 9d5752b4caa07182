#include "server/json/events_json.h"

#include <cmath>

#include "server/json/codec.h"
#include "server/json/robots_json.h"

namespace wm::json_codec {

nlohmann::json scan_event(std::int64_t scan_seq, const std::string& observer, const std::string& sensor,
                          const fusion::Pose2D& pose, const Eigen::AlignedBox2d& changed,
                          const std::vector<Eigen::Vector2d>& points) {
  nlohmann::json returns = nlohmann::json::array();
  for (const auto& p : points) returns.push_back({std::round(p.x() * 1000) / 1000, std::round(p.y() * 1000) / 1000});
  return {{"type", "scan"},
          {"scan_seq", scan_seq},
          {"observer", observer},
          {"sensor", sensor},
          {"pose", {{"x", pose.x_m}, {"y", pose.y_m}, {"theta", pose.theta_rad}}},
          {"grid_revision", scan_seq},
          {"bbox", {changed.min().x(), changed.min().y(), changed.max().x(), changed.max().y()}},
          {"points", std::move(returns)}};
}

nlohmann::json update_event(std::int64_t observation_seq, const std::string& origin, const world::UpdateResult& update,
                            const std::set<std::string>& removed_objects, const world::WorldOptions& options) {
  nlohmann::json decisions = nlohmann::json::array(), elements = nlohmann::json::array(),
                 objects = nlohmann::json::array(), removed = nlohmann::json::array();
  for (const auto& d : update.decisions) decisions.push_back(decision_json(d));
  for (auto number : update.changed_elements) elements.push_back(element_json(update.state.elements.at(number)));
  for (auto index : update.changed_objects) objects.push_back(object_json(update.state.objects.at(index), options));
  for (auto number : update.removed_elements) removed.push_back(world::element_id(number));
  return {{"type", "update"},
          {"observation", observation_seq},
          {"version", update.state.version},
          {"origin", origin},
          {"decisions", std::move(decisions)},
          {"elements", std::move(elements)},
          {"removed", std::move(removed)},
          {"removed_objects", removed_objects},
          {"objects", std::move(objects)}};
}

nlohmann::json floorplan_event(std::int64_t version, const std::string& name, std::size_t objects) {
  return {{"type", "floorplan"}, {"version", version}, {"name", name}, {"objects", objects}};
}

nlohmann::json rules_event(const rules::RulesStatus& status) {
  return {{"type", "rules"}, {"status", rules_status_json(status)}};
}

nlohmann::json robot_event(const service::RobotState& robot, const char* status, double now_unix_s) {
  return {{"type", "robot"}, {"robot", robot_json(robot, status, now_unix_s)}};
}

nlohmann::json change_event(const std::string& change_id, const std::string& verdict, std::int64_t version) {
  return {{"type", "change"}, {"change", change_id}, {"verdict", verdict}, {"version", version}};
}

nlohmann::json placement_event(std::int64_t version, const fusion::Similarity2D& placement,
                               const Eigen::Matrix4d& placement_cov, const world::DecisionRecord& decision) {
  return {{"type", "placement"},
          {"version", version},
          {"placement", placement_json(placement, placement_cov)},
          {"rule", decision.rule},
          {"explanation", decision.explanation}};
}

nlohmann::json georeference_event(std::int64_t version) { return {{"type", "georeference"}, {"version", version}}; }

}  // namespace wm::json_codec
