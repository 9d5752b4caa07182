#include "clients/robot/odometry.h"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace wm::robot {

namespace {

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument("DiffDriveOdometry: " + message);
}

bool positive_finite(double v) { return std::isfinite(v) && v > 0.0; }
bool non_negative_finite(double v) { return std::isfinite(v) && v >= 0.0; }

/// (−π, π] [rad].
double normalize_angle(double a) {
  a = std::remainder(a, 2.0 * std::numbers::pi);  // [−π, π]
  return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

void require_finite_pose(const OdometryPose& pose) {
  require(std::isfinite(pose.x_m) && std::isfinite(pose.y_m) && std::isfinite(pose.theta_rad) &&
              pose.covariance.allFinite(),
          "pose must be finite");
}

const MotorRecord* find_motor(const TelemetryPacket& packet, std::uint8_t id) {
  for (const MotorRecord& m : packet.motors) {
    if (m.device_id == id) return &m;
  }
  return nullptr;
}

}  // namespace

DiffDriveOdometry::DiffDriveOdometry(const OdometryOptions& options, const OdometryPose& start)
    : options_(options), pose_(start) {
  require(options_.left_track_id != options_.right_track_id, "left_track_id and right_track_id must differ");
  require(positive_finite(options_.position_units_per_m), "position_units_per_m must be finite and > 0");
  require(positive_finite(options_.track_width_m), "track_width_m must be finite and > 0");
  require(positive_finite(options_.max_step_m), "max_step_m must be finite and > 0");
  require(options_.left_sign == 1 || options_.left_sign == -1, "left_sign must be +1 or -1");
  require(options_.right_sign == 1 || options_.right_sign == -1, "right_sign must be +1 or -1");
  require(options_.position_bits >= 1 && options_.position_bits <= 32, "position_bits must be in 1..32");
  require(non_negative_finite(options_.translation_variance_per_m) &&
              non_negative_finite(options_.rotation_variance_per_rad) &&
              non_negative_finite(options_.rotation_variance_per_m),
          "variances must be finite and >= 0");
  require_finite_pose(start);
  pose_.theta_rad = normalize_angle(pose_.theta_rad);
}

double DiffDriveOdometry::track_delta_m(std::uint32_t from, std::uint32_t to, int sign) const {
  // Modular difference: the shortest signed way from `from` to `to` on a counter of position_bits bits.
  const std::uint64_t modulus = std::uint64_t{1} << options_.position_bits;
  const std::uint64_t mask = modulus - 1;
  const std::uint64_t forward = (std::uint64_t{to} - std::uint64_t{from}) & mask;
  const std::int64_t counts = forward >= modulus / 2
                                  ? static_cast<std::int64_t>(forward) - static_cast<std::int64_t>(modulus)
                                  : static_cast<std::int64_t>(forward);
  return sign * static_cast<double>(counts) / options_.position_units_per_m;
}

OdometryUpdate DiffDriveOdometry::update(const TelemetryPacket& packet) {
  const MotorRecord* left = find_motor(packet, options_.left_track_id);
  const MotorRecord* right = find_motor(packet, options_.right_track_id);
  if (left == nullptr || right == nullptr) return OdometryUpdate::track_missing;

  const Reference now{packet.tick, left->position, right->position};
  if (!reference_) {
    reference_ = now;
    return OdometryUpdate::started;
  }
  if (packet.tick <= reference_->tick) {
    if (reference_->tick - packet.tick <= options_.reorder_window_ticks) return OdometryUpdate::stale;
    reference_ = now;  // the tick went far back: the robot restarted and its counts with it
    return OdometryUpdate::started;
  }

  const double dl = track_delta_m(reference_->left, now.left, options_.left_sign);
  const double dr = track_delta_m(reference_->right, now.right, options_.right_sign);
  reference_ = now;
  if (std::abs(dl) > options_.max_step_m || std::abs(dr) > options_.max_step_m) {
    return OdometryUpdate::jump_rejected;
  }
  advance(0.5 * (dl + dr), (dr - dl) / options_.track_width_m);
  return OdometryUpdate::advanced;
}

void DiffDriveOdometry::advance(double distance_m, double rotation_rad) {
  if (!std::isfinite(distance_m) || !std::isfinite(rotation_rad)) {
    throw std::invalid_argument("DiffDriveOdometry::advance: non-finite step");
  }
  const double ds = distance_m;
  const double dtheta = rotation_rad;
  const double mid = pose_.theta_rad + 0.5 * dtheta;
  const double c = std::cos(mid);
  const double s = std::sin(mid);

  Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
  f(0, 2) = -ds * s;
  f(1, 2) = ds * c;
  Eigen::Matrix<double, 3, 2> g;
  g << c, -0.5 * ds * s,  //
      s, 0.5 * ds * c,    //
      0.0, 1.0;
  const double var_s = options_.translation_variance_per_m * std::abs(ds);
  const double var_theta =
      options_.rotation_variance_per_rad * std::abs(dtheta) + options_.rotation_variance_per_m * std::abs(ds);
  const Eigen::Matrix2d q = Eigen::Vector2d(var_s, var_theta).asDiagonal();

  pose_.covariance = f * pose_.covariance * f.transpose() + g * q * g.transpose();
  pose_.covariance = 0.5 * (pose_.covariance + pose_.covariance.transpose());  // keep it exactly symmetric
  pose_.x_m += ds * c;
  pose_.y_m += ds * s;
  pose_.theta_rad = normalize_angle(pose_.theta_rad + dtheta);
  distance_m_ += std::abs(ds);
  rotation_rad_ += std::abs(dtheta);
}

void DiffDriveOdometry::set_pose(const OdometryPose& pose) {
  require_finite_pose(pose);
  pose_ = pose;
  pose_.theta_rad = normalize_angle(pose_.theta_rad);
}

}  // namespace wm::robot
