// L298N / TB6612FNG H-bridge driver over GpioLines + PwmChannel (truth tables in motors.hpp and
// docs/robot.md).
#include <algorithm>
#include <cmath>

#include "fuzzystereo/robot/motors.hpp"

namespace fs::robot {

HBridgeMotors::HBridgeMotors(const MotorParams& p, GpioLines& lines, std::unique_ptr<PwmChannel> left_pwm,
                             std::unique_ptr<PwmChannel> right_pwm)
    : p_(p), lines_(lines), lpwm_(std::move(left_pwm)), rpwm_(std::move(right_pwm)) {
  st_.backend = std::string(p.driver == MotorDriverChip::kL298N ? "l298n" : "tb6612") + " on " + lines.describe();
  for (int off : {p_.left_in1, p_.left_in2, p_.right_in1, p_.right_in2}) lines_.request_output(off, 0);
  lpwm_->set_duty(0.0);
  rpwm_->set_duty(0.0);
  if (p_.driver == MotorDriverChip::kTB6612 && p_.stby >= 0) lines_.request_output(p_.stby, 1);
  stop();  // start in the configured stop state
  st_.stops = 0;
}

HBridgeMotors::~HBridgeMotors() {
  try {
    stop();
    if (p_.driver == MotorDriverChip::kTB6612 && p_.stby >= 0) lines_.set(p_.stby, 0);  // standby
    lpwm_->disable();
    rpwm_->disable();
  } catch (...) {  // nothing sensible left to do in a destructor; the PWM channels disable themselves
  }
}

void HBridgeMotors::stop_side(int in1, int in2, PwmChannel& pwm) {
  const bool l298 = p_.driver == MotorDriverChip::kL298N;
  if (p_.stop_mode == StopMode::kBrake) {
    if (l298) {  // IN1 = IN2 = 0 with EN high: fast motor stop
      lines_.set(in1, 0);
      lines_.set(in2, 0);
      pwm.set_duty(1.0);
    } else {  // TB6612: IN1 = IN2 = 1: short brake (PWM ignored)
      pwm.set_duty(0.0);
      lines_.set(in1, 1);
      lines_.set(in2, 1);
    }
  } else {
    pwm.set_duty(l298 ? 0.0 : 1.0);  // L298N: EN low = free running; TB6612: IN 00 + PWM H = off
    lines_.set(in1, 0);
    lines_.set(in2, 0);
  }
}

void HBridgeMotors::apply_side(int in1, int in2, PwmChannel& pwm, double cmd) {
  const double duty = std::abs(cmd) * p_.max_duty;
  if (duty < 1e-6) {
    stop_side(in1, in2, pwm);
    return;
  }
  const int a = cmd > 0 ? 1 : 0, b = cmd > 0 ? 0 : 1;
  pwm.set_duty(0.0);  // no drive while the direction lines change
  lines_.set(in1, a);
  lines_.set(in2, b);
  pwm.set_duty(duty);
}

void HBridgeMotors::set(double left, double right) {
  std::lock_guard<std::mutex> lk(m_);
  if (!std::isfinite(left) || !std::isfinite(right)) left = right = 0.0;
  left = std::clamp(left, -1.0, 1.0) * (p_.invert_left ? -1.0 : 1.0);
  right = std::clamp(right, -1.0, 1.0) * (p_.invert_right ? -1.0 : 1.0);
  apply_side(p_.left_in1, p_.left_in2, *lpwm_, left);
  apply_side(p_.right_in1, p_.right_in2, *rpwm_, right);
  st_.left = p_.invert_left ? -left : left;
  st_.right = p_.invert_right ? -right : right;
  st_.stopped = left == 0.0 && right == 0.0;
  ++st_.commands;
}

void HBridgeMotors::stop() {
  std::lock_guard<std::mutex> lk(m_);
  stop_side(p_.left_in1, p_.left_in2, *lpwm_);
  stop_side(p_.right_in1, p_.right_in2, *rpwm_);
  st_.left = st_.right = 0.0;
  st_.stopped = true;
  ++st_.stops;
}

MotorStatus HBridgeMotors::status() const {
  std::lock_guard<std::mutex> lk(m_);
  return st_;
}

namespace {
// Owns the chip handle, the PWM channels (inside HBridgeMotors) and the driver; members are
// destroyed bottom-up, so the motors stop before the lines are released.
class OwnedHBridge final : public MotorDriver {
 public:
  OwnedHBridge(std::unique_ptr<GpioLines> lines) : lines_(std::move(lines)) {}
  void attach(std::unique_ptr<HBridgeMotors> m) { m_ = std::move(m); }
  GpioLines& lines() { return *lines_; }
  ~OwnedHBridge() override {
    m_.reset();
    if (lines_) lines_->release_all();
  }
  void set(double l, double r) override { m_->set(l, r); }
  void stop() override { m_->stop(); }
  MotorStatus status() const override { return m_->status(); }

 private:
  std::unique_ptr<GpioLines> lines_;
  std::unique_ptr<HBridgeMotors> m_;
};
}  // namespace

std::unique_ptr<MotorDriver> open_gpiod_motors(const MotorParams& p) {
  auto owned = std::make_unique<OwnedHBridge>(open_gpiod_lines(p.gpio_chip, "fuzzystereo-motors"));
  std::unique_ptr<PwmChannel> l, r;
  if (p.pwm_mode == PwmMode::kHardware) {
    l = std::make_unique<SysfsPwmChannel>(p.pwm_sysfs_root, p.pwm_chip, p.left_pwm_channel, p.pwm_frequency_hz);
    r = std::make_unique<SysfsPwmChannel>(p.pwm_sysfs_root, p.pwm_chip, p.right_pwm_channel, p.pwm_frequency_hz);
  } else {
    l = std::make_unique<SoftPwmChannel>(owned->lines(), p.left_pwm_line, p.pwm_frequency_hz);
    r = std::make_unique<SoftPwmChannel>(owned->lines(), p.right_pwm_line, p.pwm_frequency_hz);
  }
  owned->attach(std::make_unique<HBridgeMotors>(p, owned->lines(), std::move(l), std::move(r)));
  return owned;
}

}  // namespace fs::robot
