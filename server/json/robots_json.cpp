#include "server/json/robots_json.h"

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>

#include "apriori/import/json_limits.h"
#include "server/json/codec.h"
#include "server/json/codec_error.h"

namespace wm::json_codec {
namespace {

using nlohmann::json;

double number(const json& body, const char* key, double limit, std::optional<double> fallback = std::nullopt) {
  if (!body.contains(key)) {
    if (fallback) return *fallback;
    throw bad_request(key, "missing");
  }
  const auto& value = body[key];
  if (!value.is_number()) throw bad_request(key, "expected a number");
  const double v = value.get<double>();
  if (!std::isfinite(v)) throw bad_request(key, "not a finite number");
  if (std::abs(v) > limit) throw bad_request(key, "absurd value (more than " + std::to_string(limit) + ")");
  return v;
}

json pose_json(const service::RobotPose& pose) {
  json j = {{"x", pose.x},
            {"y", pose.y},
            {"theta", pose.theta},
            {"stamp", pose.stamp_s},
            {"received_at", pose.received_at_unix_s},
            {"via", pose.via},
            {"source", pose.via}};  // the name before "via", kept for clients
  if (pose.cov) {
    json rows = json::array();
    for (int r = 0; r < 3; ++r) rows.push_back(json::array({(*pose.cov)(r, 0), (*pose.cov)(r, 1), (*pose.cov)(r, 2)}));
    j["cov"] = std::move(rows);
  }
  return j;
}

std::uint64_t integer(const json& value, const std::string& at, std::uint64_t max) {
  if (!value.is_number_integer() && !value.is_number_unsigned()) throw bad_request(at, "expected an integer");
  if (value.is_number_integer() && value.get<std::int64_t>() < 0) throw bad_request(at, "negative");
  const auto v = value.get<std::uint64_t>();
  if (v > max) throw bad_request(at, "more than " + std::to_string(max));
  return v;
}

json nullable_number(const json& value, const std::string& at) {
  if (value.is_null()) return nullptr;
  if (!value.is_number()) throw bad_request(at, "expected a number or null");
  const double v = value.get<double>();
  if (!std::isfinite(v) || std::abs(v) > 1e6) throw bad_request(at, "expected a finite number (|x| ≤ 1e6)");
  return v;
}

}  // namespace

json robot_json(const service::RobotState& robot, const char* status, double now_unix_s) {
  json sensors = json::array();
  for (const auto& [sensor, count] : robot.scans) sensors.push_back(sensor);
  if (robot.primitives > 0) sensors.push_back("primitives");
  if (robot.poses > 0) sensors.push_back("pose");
  json track = json::array();
  for (const auto& p : robot.track) track.push_back({p.x, p.y, p.theta, p.received_at_unix_s});
  return {{"id", robot.id},
          {"status", status},
          {"pose", robot.pose ? pose_json(*robot.pose) : json(nullptr)},
          {"first_seen", robot.first_seen_unix_s},
          {"last_seen", robot.last_seen_unix_s},
          {"silent_s", std::max(0.0, now_unix_s - robot.last_seen_unix_s)},
          {"sensors", std::move(sensors)},
          {"scans", robot.scans},
          {"primitives", robot.primitives},
          {"poses", robot.poses},
          {"track", std::move(track)}};
}

ReportedPose parse_reported_pose(std::string_view text) {
  if (auto error = apriori::json_nesting_error(text)) throw bad_request("", *error);
  json body;
  try {
    body = json::parse(text.begin(), text.end());
  } catch (const json::parse_error& e) {
    throw bad_request("", std::string("malformed JSON: ") + e.what());
  } catch (const json::out_of_range& e) {
    throw bad_request("", std::string("number out of range (must be finite): ") + e.what());
  }
  if (!body.is_object()) throw bad_request("", "expected an object {\"x\", \"y\", \"theta\", ...}");
  for (const auto& [key, value] : body.items())
    if (key != "x" && key != "y" && key != "theta" && key != "cov" && key != "stamp" && key != "state" &&
        key != "telemetry")
      throw bad_request(key, "unknown field (x, y, theta, cov, stamp, state, telemetry)");
  ReportedPose reported;
  auto& pose = reported.pose;
  pose.x = number(body, "x", 1e5);
  pose.y = number(body, "y", 1e5);
  pose.theta = number(body, "theta", 1e3);
  pose.stamp_s = number(body, "stamp", 1e12, 0.0);
  if (body.contains("cov")) {
    const auto& cov = body["cov"];
    if (!cov.is_array() || cov.size() != 3) throw bad_request("cov", "expected a 3×3 array over (x, y, theta)");
    Eigen::Matrix3d m;
    for (std::size_t r = 0; r < 3; ++r) {
      const std::string row = "cov[" + std::to_string(r) + "]";
      if (!cov[r].is_array() || cov[r].size() != 3) throw bad_request(row, "expected 3 numbers");
      for (std::size_t c = 0; c < 3; ++c) {
        const auto& v = cov[r][c];
        const std::string at = row + "[" + std::to_string(c) + "]";
        if (!v.is_number() || !std::isfinite(v.get<double>())) throw bad_request(at, "expected a finite number");
        m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = v.get<double>();
      }
    }
    json_codec::require_pose_covariance(m, "cov");
    pose.cov = m;
  }
  if (body.contains("state")) {
    const auto& state = body["state"];
    if (!state.is_string() || (state != "moving" && state != "stopped"))
      throw bad_request("state", "expected \"moving\" or \"stopped\"");
    reported.stopped = state == "stopped";
  }
  if (body.contains("telemetry")) reported.telemetry = parse_robot_telemetry(body["telemetry"]);
  return reported;
}

json parse_robot_telemetry(const json& telemetry) {
  if (!telemetry.is_object()) throw bad_request("telemetry", "expected an object {\"motors\": [...]}");
  json out = json::object();
  bool any_fault = false;
  for (const auto& [key, value] : telemetry.items()) {
    const std::string at = "telemetry." + key.substr(0, 64);
    if (key == "motors") {
      if (!value.is_array() || value.size() > 16) throw bad_request(at, "expected at most 16 motors");
      json motors = json::array();
      for (std::size_t i = 0; i < value.size(); ++i) {
        const auto& m = value[i];
        const std::string mat = at + "[" + std::to_string(i) + "]";
        if (!m.is_object()) throw bad_request(mat, "expected an object");
        json motor = json::object();
        for (const auto& [field, v] : m.items()) {
          const std::string fat = mat + "." + field.substr(0, 64);
          if (field == "id" || field == "state" || field == "mode") {
            motor[field] = integer(v, fat, 255);
          } else if (field == "faults" || field == "status_bits") {
            motor[field] = integer(v, fat, 65535);
          } else if (field == "current" || field == "temperature") {
            motor[field] = nullable_number(v, fat);
          } else if (field == "fault") {
            if (!v.is_boolean()) throw bad_request(fat, "expected true or false");
            motor[field] = v.get<bool>();
            any_fault = any_fault || v.get<bool>();
          } else {
            throw bad_request(fat,
                              "unknown field (id, state, mode, current, temperature, fault, faults, "
                              "status_bits)");
          }
        }
        if (!motor.contains("id")) throw bad_request(mat + ".id", "missing");
        for (const char* field : {"current", "temperature"})
          if (!motor.contains(field)) motor[field] = nullptr;
        if (!motor.contains("fault")) motor["fault"] = false;
        if (!motor.contains("faults")) motor["faults"] = 0;
        motors.push_back(std::move(motor));
      }
      out["motors"] = std::move(motors);
    } else if (key == "current_unit" || key == "temperature_unit") {
      if (!value.is_string() || value.get_ref<const std::string&>().size() > 32)
        throw bad_request(at, "expected a string of at most 32 characters");
      out[key] = value;
    } else {
      throw bad_request(at, "unknown field (motors, current_unit, temperature_unit)");
    }
  }
  if (!out.contains("motors")) throw bad_request("telemetry.motors", "missing");
  out["fault"] = any_fault;
  return out;
}

bool valid_robot_id(std::string_view id) {
  if (id.empty() || id.size() > 128) return false;
  for (const char c : id) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == ':' || c == '-';
    if (!ok) return false;
  }
  return true;
}

}  // namespace wm::json_codec
