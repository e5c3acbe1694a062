// Differential-drive dead reckoning from wheel surface speeds (commanded or measured).
#pragma once
#include "fuzzystereo/robot/geometry.hpp"

namespace fs::robot {

struct BodyTwist {
  double v = 0;      // forward speed [m/s]
  double omega = 0;  // yaw rate [rad/s], counter-clockwise positive
};

// v = (vl + vr) / 2, omega = (vr - vl) / wheel_base.
BodyTwist twist_from_wheels(double v_left, double v_right, double wheel_base_m);
// Inverse: vl = v - omega b / 2, vr = v + omega b / 2.
void wheels_from_twist(const BodyTwist& t, double wheel_base_m, double& v_left, double& v_right);

// Exact integration of a constant twist over dt (circular arc; straight line when omega ~ 0).
Pose2D integrate_pose(const Pose2D& p, const BodyTwist& t, double dt);

class DiffDriveOdometry {
 public:
  explicit DiffDriveOdometry(double wheel_base_m, Pose2D start = {}) : b_(wheel_base_m), pose_(start) {}
  // Wheel speeds held constant over dt [s].
  void update(double v_left, double v_right, double dt);
  const Pose2D& pose() const { return pose_; }
  void reset(Pose2D p) { pose_ = p; }
  double distance_travelled() const { return dist_; }

 private:
  double b_;
  Pose2D pose_;
  double dist_ = 0;
};

}  // namespace fs::robot
