#include <algorithm>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "clients/robot/servosila_bridge.h"
#include "clients/wmctl/http_client.h"

// Where the bridge's poses go over HTTP: the body of the pose PUT and the sink that sends it.
namespace wm::robot {

std::string pose_report_json(const PoseReport& report) {
  const OdometryPose& p = report.pose;
  nlohmann::json cov = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) cov.push_back({p.covariance(r, 0), p.covariance(r, 1), p.covariance(r, 2)});
  nlohmann::json body = {{"x", p.x_m},
                         {"y", p.y_m},
                         {"theta", p.theta_rad},
                         {"cov", std::move(cov)},
                         {"stamp", report.stamp_unix_s},
                         {"state", report.moving ? "moving" : "stopped"}};
  if (report.has_telemetry) {
    nlohmann::json motors = nlohmann::json::array();
    for (const MotorRecord& m : report.motors) {
      if (motors.size() == 16) break;  // wmd's limit; the protocol allows 10
      motors.push_back({{"id", m.device_id},
                        {"state", m.device_state},
                        {"mode", m.operation_mode},
                        {"current", m.amps},
                        {"temperature", nullptr},
                        {"fault", m.fault_detected != 0},
                        {"faults", m.faults_counter},
                        {"status_bits", static_cast<std::uint16_t>(m.status_bits)}});
    }
    body["telemetry"] = {{"motors", std::move(motors)}, {"current_unit", "raw"}, {"temperature_unit", "none"}};
  }
  return body.dump();
}

bool valid_robot_id(std::string_view id) {
  if (id.empty() || id.size() > 128) return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == ':' || c == '-';
  });
}

struct HttpPoseSink::Impl {
  client::HttpClient client;
  std::string target;
  std::string token;
};

HttpPoseSink::HttpPoseSink(const std::string& server_url, const std::string& robot_id, const std::string& token,
                           std::chrono::seconds timeout) {
  if (!valid_robot_id(robot_id)) {
    throw std::invalid_argument("robot id '" + robot_id + "': expected 1 to 128 of A-Z a-z 0-9 . _ : -");
  }
  impl_ = std::make_unique<Impl>(
      Impl{client::HttpClient(server_url, timeout), "/api/v1/robots/" + robot_id + "/pose", token});
}

HttpPoseSink::~HttpPoseSink() = default;

void HttpPoseSink::publish(const PoseReport& report) {
  const client::HttpResult r =
      impl_->client.request("PUT", impl_->target, pose_report_json(report), "application/json", impl_->token);
  if (r.status < 200 || r.status > 299) {
    throw std::runtime_error("PUT " + impl_->target + ": HTTP " + std::to_string(r.status) + ": " +
                             r.body.substr(0, 300));
  }
}

}  // namespace wm::robot
