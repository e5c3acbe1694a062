#include <algorithm>
#include <cmath>

#include "fuzzystereo/robot/motors.hpp"
#include "fuzzystereo/robot/odometry.hpp"

namespace fs::robot {

namespace {
double clamp_cmd(double c) { return std::isfinite(c) ? std::clamp(c, -1.0, 1.0) : 0.0; }
constexpr std::int64_t kMaxStepNs = 5'000'000;  // kinematics integration step
}  // namespace

SimMotors::SimMotors(const RobotParams& rp, Pose2D start, std::int64_t t0_ns) : rp_(rp), pose_(start), t_ns_(t0_ns) {
  st_.backend = "sim";
}

void SimMotors::set(double left, double right) {
  std::lock_guard<std::mutex> lk(m_);
  if (!std::isfinite(left) || !std::isfinite(right)) left = right = 0.0;
  st_.left = clamp_cmd(left);
  st_.right = clamp_cmd(right);
  st_.stopped = st_.left == 0.0 && st_.right == 0.0;
  ++st_.commands;
  target_l_ = st_.left * rp_.max_wheel_speed_mps;
  target_r_ = st_.right * rp_.max_wheel_speed_mps;
}

void SimMotors::stop() {
  std::lock_guard<std::mutex> lk(m_);
  st_.left = st_.right = 0.0;
  st_.stopped = true;
  ++st_.stops;
  target_l_ = target_r_ = 0.0;
}

MotorStatus SimMotors::status() const {
  std::lock_guard<std::mutex> lk(m_);
  return st_;
}

void SimMotors::advance_to(std::int64_t t_ns) {
  std::lock_guard<std::mutex> lk(m_);
  while (t_ns_ < t_ns) {
    const std::int64_t step = std::min(kMaxStepNs, t_ns - t_ns_);
    const double dt = ns_to_s(step);
    const double dv = rp_.max_accel_mps2 * dt;
    const double wl0 = wl_, wr0 = wr_;
    wl_ += std::clamp(target_l_ - wl_, -dv, dv);
    wr_ += std::clamp(target_r_ - wr_, -dv, dv);
    // trapezoid: mean wheel speed over the step
    pose_ = integrate_pose(pose_, twist_from_wheels(0.5 * (wl0 + wl_), 0.5 * (wr0 + wr_), rp_.wheel_base_m), dt);
    t_ns_ += step;
  }
}

Pose2D SimMotors::pose() const {
  std::lock_guard<std::mutex> lk(m_);
  return pose_;
}
double SimMotors::wheel_left_mps() const {
  std::lock_guard<std::mutex> lk(m_);
  return wl_;
}
double SimMotors::wheel_right_mps() const {
  std::lock_guard<std::mutex> lk(m_);
  return wr_;
}

}  // namespace fs::robot
