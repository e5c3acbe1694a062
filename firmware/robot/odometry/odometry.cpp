#include "fuzzystereo/robot/odometry.hpp"

#include <cmath>

namespace fs::robot {

BodyTwist twist_from_wheels(double v_left, double v_right, double wheel_base_m) {
  return {0.5 * (v_left + v_right), (v_right - v_left) / wheel_base_m};
}

void wheels_from_twist(const BodyTwist& t, double wheel_base_m, double& v_left, double& v_right) {
  v_left = t.v - 0.5 * t.omega * wheel_base_m;
  v_right = t.v + 0.5 * t.omega * wheel_base_m;
}

Pose2D integrate_pose(const Pose2D& p, const BodyTwist& t, double dt) {
  Pose2D q = p;
  const double dth = t.omega * dt;
  if (std::abs(dth) < 1e-9) {
    q.x += t.v * dt * std::cos(p.yaw);
    q.y += t.v * dt * std::sin(p.yaw);
  } else {  // exact circular arc of radius v / omega
    const double r = t.v / t.omega;
    q.x += r * (std::sin(p.yaw + dth) - std::sin(p.yaw));
    q.y -= r * (std::cos(p.yaw + dth) - std::cos(p.yaw));
  }
  q.yaw = wrap_angle(p.yaw + dth);
  return q;
}

void DiffDriveOdometry::update(double v_left, double v_right, double dt) {
  const BodyTwist t = twist_from_wheels(v_left, v_right, b_);
  pose_ = integrate_pose(pose_, t, dt);
  dist_ += std::abs(t.v) * dt;
}

}  // namespace fs::robot
