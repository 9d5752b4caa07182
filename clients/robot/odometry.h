#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>

#include "clients/robot/servosila_protocol.h"

namespace wm::robot {

/// A planar pose with its covariance, in the odometry frame (x forward at the start, y left, θ counter-clockwise).
struct OdometryPose {
  double x_m = 0.0;
  double y_m = 0.0;
  double theta_rad = 0.0;  // in (−π, π]
  /// Covariance of (x [m], y [m], θ [rad]); symmetric positive semi-definite.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

/// Differential-drive odometry from the two track motors. What the seed does not fix (which motor ids are the
/// tracks, their counts per metre, their signs) defaults to the simulator's conventions and must be configured
/// for a real robot. Note that the paper reports that the Engineer's chassis motors give no position telemetry
/// at all (it dead-reckons from speed × time); advance() serves that case with displacements integrated from
/// the commanded velocity.
struct OdometryOptions {
  std::uint8_t left_track_id = 0;   // device id of the left track's motor record
  std::uint8_t right_track_id = 1;  // device id of the right track's motor record (≠ left)
  /// Encoder counts per metre of track travel (> 0). The default is the simulator's: 0.1 mm per count.
  double position_units_per_m = 10000.0;
  /// +1 when the count grows as the track moves the robot forward, −1 for a mirrored motor.
  int left_sign = 1;
  int right_sign = 1;
  /// Distance between the tracks' effective contact lines [m] (> 0). Default 0.2 m: the seed's angular
  /// constant assumes the robot turns on the spot with its tracks on a 0.1 m radius, so this is the width that
  /// agrees with 24 000 units per rad/s (and the simulator's), not a measured chassis dimension.
  double track_width_m = 0.2;
  /// The position field is a uint32; a controller may count on fewer bits. Counts wrap at 2^bits (1..32), and a
  /// track must move less than half of that between two packets.
  unsigned position_bits = 32;
  /// A track that moves further than this between two packets [m] (> 0) is taken for a counter reset or a
  /// corrupt record: the counts become the new reference and the pose does not move.
  double max_step_m = 1.0;
  /// A packet whose tick is at most this far behind the last applied one is a late (reordered or duplicated)
  /// packet and is ignored; further behind, the robot has restarted and the counts are re-referenced.
  std::uint64_t reorder_window_ticks = 1000;
  /// Noise model, per step (Δs travelled [m], Δθ turned [rad]): var(Δs) = translation_variance_per_m·|Δs|
  /// [m²/m], var(Δθ) = rotation_variance_per_rad·|Δθ| + rotation_variance_per_m·|Δs| [rad²/rad, rad²/m]
  /// (the second term: heading drift from track slip while driving). All ≥ 0. Defaults: σ 5 cm per √m,
  /// about 5° per √rad and 1° per √m.
  double translation_variance_per_m = 0.0025;
  double rotation_variance_per_rad = 0.0076;
  double rotation_variance_per_m = 0.0003;
};

/// What update() did with a packet.
enum class OdometryUpdate {
  started,        // first packet (or a robot restart): counts taken as the reference, pose unchanged
  advanced,       // the pose moved by the tracks' motion since the last applied packet
  stale,          // tick not newer than the last applied one (within the reorder window): ignored
  track_missing,  // a track's motor record is absent: ignored
  jump_rejected,  // a track moved more than max_step_m: re-referenced, pose unchanged
};

/// Integrates the tracks' motion into a pose whose covariance grows with the distance travelled and the angle
/// turned. Each step uses the midpoint heading, x += Δs·cos(θ + Δθ/2), y += Δs·sin(θ + Δθ/2), θ += Δθ, with
/// Δs = (Δl + Δr)/2 and Δθ = (Δr − Δl)/track width, and propagates P ← F·P·Fᵀ + G·Q·Gᵀ (F, G the Jacobians
/// of that step in the pose and in (Δs, Δθ); Q = diag(var Δs, var Δθ) as in OdometryOptions): first-order
/// propagation of a step noise proportional to the step, as in the odometry error model of Siegwart and
/// Nourbakhsh (Introduction to Autonomous Mobile Robots, 2nd ed., §5.2.4), with the noise in (Δs, Δθ) instead
/// of per wheel so that translation and rotation have their own rates.
class DiffDriveOdometry {
 public:
  /// @throw std::invalid_argument for equal track ids, a non-positive or non-finite width, counts per metre or
  ///        max step, a sign other than ±1, position_bits outside 1..32, a negative or non-finite variance,
  ///        or a non-finite start pose.
  explicit DiffDriveOdometry(const OdometryOptions& options = {}, const OdometryPose& start = {});

  /// Applies one telemetry packet (see OdometryUpdate). Counts wrap around modulo 2^position_bits.
  OdometryUpdate update(const TelemetryPacket& packet);

  /// Moves the pose by one step: `distance_m` along the midpoint heading and `rotation_rad` counter-clockwise.
  /// For dead reckoning from commands, pass v·Δt and ω·Δt over a short Δt.
  /// @throw std::invalid_argument for a non-finite argument (the pose is left unchanged).
  void advance(double distance_m, double rotation_rad);

  const OdometryPose& pose() const { return pose_; }
  /// Replaces the pose (e.g. after a localisation fix); the encoder reference is kept.
  /// @throw std::invalid_argument for a non-finite pose.
  void set_pose(const OdometryPose& pose);
  /// Total |Δs| [m] and |Δθ| [rad] integrated so far.
  double distance_travelled_m() const { return distance_m_; }
  double rotation_turned_rad() const { return rotation_rad_; }

 private:
  struct Reference {
    std::uint64_t tick;
    std::uint32_t left;
    std::uint32_t right;
  };
  double track_delta_m(std::uint32_t from, std::uint32_t to, int sign) const;

  const OdometryOptions options_;
  OdometryPose pose_;
  std::optional<Reference> reference_;
  double distance_m_ = 0.0;
  double rotation_rad_ = 0.0;
};

}  // namespace wm::robot
