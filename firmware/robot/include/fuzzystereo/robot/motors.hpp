// Motor HAL. MotorDriver is what the robot loop talks to; SimMotors is its simulated twin (and the
// simulator's ground truth pose); HBridgeMotors drives an L298N or TB6612FNG from a Raspberry Pi
// through two small I/O interfaces, GpioLines (direction/standby lines; libgpiod 1.6 on the robot)
// and PwmChannel (speed; sysfs hardware PWM or a software-PWM thread), each with a fake for tests.
//
// Every driver starts stopped; stop() is idempotent and thread-safe (the wall-clock watchdog calls
// it from its thread); destructors stop the motors. stop() is NOT async-signal-safe: signal
// handlers only set a flag (failsafe.hpp).
#pragma once
#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "fuzzystereo/robot/clock.hpp"
#include "fuzzystereo/robot/geometry.hpp"
#include "fuzzystereo/robot/params.hpp"

namespace fs::robot {

// Missing or inaccessible hardware: one line naming what was looked for and what to check.
class HardwareError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct MotorStatus {
  double left = 0, right = 0;  // last applied command in [-1, 1]
  bool stopped = true;
  std::uint64_t commands = 0;  // set() calls applied
  std::uint64_t stops = 0;     // stop() calls
  std::string backend;
};

class MotorDriver {
 public:
  virtual ~MotorDriver() = default;
  // left/right in [-1, 1] (values outside are clamped; NaN stops the motors).
  virtual void set(double left, double right) = 0;
  virtual void stop() = 0;
  virtual MotorStatus status() const = 0;
};

// ---- simulated twin ------------------------------------------------------------------------------
// Differential-drive kinematics: the command c maps to a target wheel speed c * max_wheel_speed_mps;
// each wheel approaches it with at most max_accel_mps2 (the motor's own inertia). advance_to(t)
// integrates the pose up to simulated time t. This pose is the simulator's ground truth.
class SimMotors final : public MotorDriver {
 public:
  SimMotors(const RobotParams& rp, Pose2D start = {}, std::int64_t t0_ns = 0);
  void set(double left, double right) override;
  void stop() override;
  MotorStatus status() const override;
  void advance_to(std::int64_t t_ns);  // integrates in steps of <= 5 ms
  Pose2D pose() const;
  double wheel_left_mps() const;
  double wheel_right_mps() const;

 private:
  mutable std::mutex m_;
  RobotParams rp_;
  Pose2D pose_;
  std::int64_t t_ns_;
  double target_l_ = 0, target_r_ = 0, wl_ = 0, wr_ = 0;
  MotorStatus st_;
};

// ---- I/O interfaces ------------------------------------------------------------------------------
class GpioLines {
 public:
  virtual ~GpioLines() = default;
  // Reserve `offset` as an output at `initial` (0/1). Throws HardwareError on failure.
  virtual void request_output(int offset, int initial) = 0;
  virtual void set(int offset, int value) = 0;
  virtual void release_all() = 0;
  virtual std::string describe() const = 0;  // e.g. "gpiochip0"
};

// libgpiod 1.6 (gpiod_chip_open_by_name / gpiod_chip_get_line / gpiod_line_request_output /
// gpiod_line_set_value / gpiod_line_release). Throws HardwareError when the chip cannot be opened
// (message names /dev/<chip> and the gpio group) or when the build has no libgpiod.
std::unique_ptr<GpioLines> open_gpiod_lines(const std::string& chip_name, const std::string& consumer);
bool have_libgpiod();

class FakeGpioLines final : public GpioLines {
 public:
  void request_output(int offset, int initial) override;
  void set(int offset, int value) override;
  void release_all() override;
  std::string describe() const override { return "fake"; }
  int value(int offset) const;          // -1 when not requested
  bool requested(int offset) const;
  std::uint64_t writes(int offset) const;
  std::vector<int> fail_offsets;        // request_output throws HardwareError for these

 private:
  mutable std::mutex m_;
  std::map<int, int> values_;
  std::map<int, std::uint64_t> writes_;
};

class PwmChannel {
 public:
  virtual ~PwmChannel() = default;
  virtual void set_duty(double duty) = 0;  // [0, 1], clamped
  virtual double duty() const = 0;
  virtual void disable() = 0;              // output off (duty 0, enable 0)
  virtual std::string describe() const = 0;
};

// Linux sysfs PWM: <root>/pwmchip<chip>/{export, pwm<ch>/{period,duty_cycle,enable}} (root is
// /sys/class/pwm on the robot, a temp dir in tests). Exports the channel when pwm<ch> is absent
// and waits up to export_wait_ms for it (udev sets its permissions asynchronously). Throws
// HardwareError naming the path and what to check (dtoverlay, pwm group/udev rule).
class SysfsPwmChannel final : public PwmChannel {
 public:
  SysfsPwmChannel(const std::string& root, int chip, int channel, double frequency_hz, int export_wait_ms = 1000);
  ~SysfsPwmChannel() override;
  void set_duty(double duty) override;
  double duty() const override { return duty_; }
  void disable() override;
  std::string describe() const override { return dir_; }
  std::int64_t period_ns() const { return period_ns_; }

 private:
  void write(const std::string& file, const std::string& value);
  std::string dir_;
  std::int64_t period_ns_;
  double duty_ = 0;
  bool enabled_ = false;
};

// Software PWM: a thread toggles one GPIO line (period 1/frequency). Duty 0 and 1 hold the line
// steady without toggling. Jitter is the scheduler's (~0.1 ms on a Pi): use a low frequency
// (100-500 Hz) and prefer hardware PWM.
class SoftPwmChannel final : public PwmChannel {
 public:
  SoftPwmChannel(GpioLines& lines, int offset, double frequency_hz);
  ~SoftPwmChannel() override;
  void set_duty(double duty) override;
  double duty() const override { return duty_.load(); }
  void disable() override { set_duty(0.0); }
  std::string describe() const override;

 private:
  void run();
  void loop();
  GpioLines& lines_;
  int offset_;
  std::int64_t period_ns_;
  std::atomic<double> duty_{0.0};
  std::atomic<bool> quit_{false};
  std::atomic<bool> failed_{false};
  std::thread thread_;
};

class FakePwm final : public PwmChannel {
 public:
  void set_duty(double d) override;
  double duty() const override { return duty_; }
  void disable() override { duty_ = 0; enabled = false; }
  std::string describe() const override { return "fake-pwm"; }
  bool enabled = false;
  std::uint64_t writes = 0;

 private:
  double duty_ = 0;
};

// ---- H-bridge driver -----------------------------------------------------------------------------
// L298N: IN1/IN2 per side give the direction (10 forward, 01 reverse), ENA/ENB carry the PWM.
//   brake: IN1 = IN2 = 0 with EN = 1 (fast motor stop); coast: EN = 0.
// TB6612FNG: AIN1/AIN2, BIN1/BIN2 direction, PWMA/PWMB speed, STBY high = enabled.
//   brake: IN1 = IN2 = 1 (short brake); coast: IN1 = IN2 = 0 with PWM = 1 ("stop", high impedance).
// Commands are multiplied by max_duty; invert_left/right flip a side whose motor is wired
// backwards.
class HBridgeMotors final : public MotorDriver {
 public:
  // lines must outlive this object; the PWM channels are owned.
  HBridgeMotors(const MotorParams& p, GpioLines& lines, std::unique_ptr<PwmChannel> left_pwm,
                std::unique_ptr<PwmChannel> right_pwm);
  ~HBridgeMotors() override;
  void set(double left, double right) override;
  void stop() override;
  MotorStatus status() const override;

 private:
  void apply_side(int in1, int in2, PwmChannel& pwm, double cmd);
  void stop_side(int in1, int in2, PwmChannel& pwm);
  MotorParams p_;
  GpioLines& lines_;
  std::unique_ptr<PwmChannel> lpwm_, rpwm_;
  mutable std::mutex m_;
  MotorStatus st_;
};

// The configured real backend ([motors] backend = "gpiod"): opens the GPIO chip, the PWM channels
// (sysfs hardware PWM or software PWM on the same chip) and returns a stopped HBridgeMotors that
// owns them. Throws HardwareError with what to check when something is missing.
std::unique_ptr<MotorDriver> open_gpiod_motors(const MotorParams& p);

}  // namespace fs::robot
