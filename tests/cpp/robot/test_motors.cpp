// Motor HAL with fakes: H-bridge truth tables, limits, stop on destruction, sysfs PWM, soft PWM,
// error messages; SimMotors kinematics.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "fuzzystereo/robot/motors.hpp"

namespace fs::robot {
namespace {
namespace fsys = std::filesystem;

// Forwards to a FakePwm the test keeps, so it can be inspected after the driver is gone.
class SharedPwm final : public PwmChannel {
 public:
  explicit SharedPwm(FakePwm& f) : f_(f) {}
  void set_duty(double d) override { f_.set_duty(d); }
  double duty() const override { return f_.duty(); }
  void disable() override { f_.disable(); }
  std::string describe() const override { return "shared"; }

 private:
  FakePwm& f_;
};

MotorParams l298() {
  MotorParams p;
  p.left_in1 = 5, p.left_in2 = 6, p.right_in1 = 20, p.right_in2 = 21;
  return p;
}

TEST(HBridge, L298ForwardReverseStop) {
  FakeGpioLines io;
  FakePwm lp, rp;
  MotorParams p = l298();
  p.stop_mode = StopMode::kCoast;
  {
    HBridgeMotors m(p, io, std::make_unique<SharedPwm>(lp), std::make_unique<SharedPwm>(rp));
    EXPECT_TRUE(m.status().stopped);  // starts stopped
    EXPECT_EQ(io.value(5), 0);
    EXPECT_EQ(lp.duty(), 0.0);
    m.set(0.5, -0.25);
    EXPECT_EQ(io.value(5), 1);
    EXPECT_EQ(io.value(6), 0);  // left forward
    EXPECT_EQ(io.value(20), 0);
    EXPECT_EQ(io.value(21), 1);  // right reverse
    EXPECT_DOUBLE_EQ(lp.duty(), 0.5);
    EXPECT_DOUBLE_EQ(rp.duty(), 0.25);
    m.set(3.0, -7.0);  // clamped
    EXPECT_DOUBLE_EQ(lp.duty(), 1.0);
    EXPECT_DOUBLE_EQ(rp.duty(), 1.0);
    EXPECT_DOUBLE_EQ(m.status().right, -1.0);
    m.set(NAN, 0.5);  // NaN -> stop both
    EXPECT_EQ(lp.duty(), 0.0);
    EXPECT_EQ(rp.duty(), 0.0);
    m.set(0.4, 0.4);
    m.stop();
    m.stop();  // idempotent
    EXPECT_EQ(io.value(5), 0);
    EXPECT_EQ(io.value(6), 0);
    EXPECT_EQ(lp.duty(), 0.0);  // coast: EN low
    EXPECT_EQ(m.status().stops, 2u);
    m.set(0.7, 0.7);
  }
  // destructor stopped the motors
  EXPECT_EQ(lp.duty(), 0.0);
  EXPECT_EQ(rp.duty(), 0.0);
  EXPECT_EQ(io.value(5), 0);
}

TEST(HBridge, L298BrakeInvertAndMaxDuty) {
  FakeGpioLines io;
  FakePwm lp, rp;
  MotorParams p = l298();
  p.invert_right = true;
  p.max_duty = 0.8;
  HBridgeMotors m(p, io, std::make_unique<SharedPwm>(lp), std::make_unique<SharedPwm>(rp));
  EXPECT_DOUBLE_EQ(lp.duty(), 1.0);  // brake at start: EN high with IN1 = IN2 = 0
  EXPECT_EQ(io.value(5) + io.value(6), 0);
  m.set(1.0, 1.0);
  EXPECT_DOUBLE_EQ(lp.duty(), 0.8);
  EXPECT_EQ(io.value(20), 0);  // right inverted: reverse lines for a forward command
  EXPECT_EQ(io.value(21), 1);
  EXPECT_DOUBLE_EQ(m.status().right, 1.0);
}

TEST(HBridge, TB6612BrakeCoastAndStandby) {
  FakeGpioLines io;
  FakePwm lp, rp;
  MotorParams p = l298();
  p.driver = MotorDriverChip::kTB6612;
  p.stby = 22;
  {
    HBridgeMotors m(p, io, std::make_unique<SharedPwm>(lp), std::make_unique<SharedPwm>(rp));
    EXPECT_EQ(io.value(22), 1);  // enabled
    EXPECT_EQ(io.value(5), 1);   // short brake: IN1 = IN2 = 1
    EXPECT_EQ(io.value(6), 1);
    m.set(-0.3, 0.6);
    EXPECT_EQ(io.value(5), 0);
    EXPECT_EQ(io.value(6), 1);
    EXPECT_DOUBLE_EQ(lp.duty(), 0.3);
  }
  EXPECT_EQ(io.value(22), 0);  // standby after destruction
  FakeGpioLines io2;
  p.stop_mode = StopMode::kCoast;
  HBridgeMotors c(p, io2, std::make_unique<SharedPwm>(lp), std::make_unique<SharedPwm>(rp));
  EXPECT_EQ(io2.value(5), 0);  // coast: IN 00 with PWM high = outputs off
  EXPECT_EQ(io2.value(6), 0);
  EXPECT_DOUBLE_EQ(lp.duty(), 1.0);
}

TEST(HBridge, BusyLineFailsClearly) {
  FakeGpioLines io;
  io.fail_offsets = {6};
  FakePwm lp, rp;
  EXPECT_THROW(HBridgeMotors(l298(), io, std::make_unique<SharedPwm>(lp), std::make_unique<SharedPwm>(rp)),
               HardwareError);
}

struct TempDir {
  fsys::path p;
  TempDir() {
    p = fsys::temp_directory_path() / ("fs_robot_pwm_" + std::to_string(::getpid()) + "_" +
                                       std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()));
    fsys::create_directories(p);
  }
  ~TempDir() { fsys::remove_all(p); }
};
std::string slurp(const fsys::path& f) {
  std::ifstream in(f);
  std::string s;
  std::getline(in, s);
  return s;
}

TEST(SysfsPwm, WritesPeriodDutyEnable) {
  TempDir t;
  const fsys::path ch = t.p / "pwmchip0" / "pwm1";
  fsys::create_directories(ch);
  std::ofstream(t.p / "pwmchip0" / "export").put('\n');
  {
    SysfsPwmChannel pwm(t.p.string(), 0, 1, 1000.0);
    EXPECT_EQ(slurp(ch / "period"), "1000000");
    EXPECT_EQ(slurp(ch / "duty_cycle"), "0");
    EXPECT_EQ(slurp(ch / "enable"), "1");
    pwm.set_duty(0.25);
    EXPECT_EQ(slurp(ch / "duty_cycle"), "250000");
    pwm.set_duty(2.0);
    EXPECT_EQ(slurp(ch / "duty_cycle"), "1000000");
  }
  EXPECT_EQ(slurp(ch / "enable"), "0");  // disabled on destruction
  EXPECT_EQ(slurp(ch / "duty_cycle"), "0");
}

TEST(SysfsPwm, MissingChipOrChannelNamesThePathAndTheFix) {
  TempDir t;
  try {
    SysfsPwmChannel pwm(t.p.string(), 3, 0, 1000.0);
    FAIL();
  } catch (const HardwareError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find((t.p / "pwmchip3").string()), std::string::npos) << m;
    EXPECT_NE(m.find("dtoverlay=pwm-2chan"), std::string::npos) << m;
  }
  fsys::create_directories(t.p / "pwmchip0");
  std::ofstream(t.p / "pwmchip0" / "export").put('\n');  // export "works" but no kernel creates pwm0
  try {
    SysfsPwmChannel pwm(t.p.string(), 0, 0, 1000.0, 30);
    FAIL();
  } catch (const HardwareError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("pwm0/period did not become writable"), std::string::npos) << m;
    EXPECT_EQ(slurp(t.p / "pwmchip0" / "export"), "0");  // it did try to export channel 0
  }
}

TEST(SoftPwm, TogglesOnlyBetweenZeroAndOne) {
  FakeGpioLines io;
  {
    SoftPwmChannel pwm(io, 12, 500.0);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    EXPECT_EQ(io.value(12), 0);
    const auto w0 = io.writes(12);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    EXPECT_LE(io.writes(12) - w0, 1u);  // duty 0: held low, no toggling
    pwm.set_duty(1.0);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    EXPECT_EQ(io.value(12), 1);
    pwm.set_duty(0.5);
    const auto w1 = io.writes(12);
    std::this_thread::sleep_for(std::chrono::milliseconds(60));
    EXPECT_GE(io.writes(12) - w1, 10u);  // 500 Hz for 60 ms: ~60 edges (scheduler permitting)
  }
  EXPECT_EQ(io.value(12), 0);  // low after destruction
}

TEST(GpiodBackend, MissingChipMessage) {
  try {
    open_gpiod_lines("gpiochip_fuzzystereo_test_missing", "test");
    FAIL();
  } catch (const HardwareError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("gpiochip_fuzzystereo_test_missing"), std::string::npos) << m;
    if (have_libgpiod()) EXPECT_NE(m.find("'gpio' group"), std::string::npos) << m;
    else EXPECT_NE(m.find("libgpiod"), std::string::npos) << m;
  }
  MotorParams p;
  p.gpio_chip = "gpiochip_fuzzystereo_test_missing";
  EXPECT_THROW(open_gpiod_motors(p), HardwareError);
}

TEST(SimMotors, KinematicsWithAccelerationLimit) {
  RobotParams rp;
  SimMotors m(rp, {0, 0, 0}, 0);
  EXPECT_TRUE(m.status().stopped);
  m.set(1.0, 1.0);
  m.advance_to(2'000'000'000);
  // ramp 0 -> 0.6 m/s at 1 m/s^2 takes 0.6 s (0.18 m), then 1.4 s at 0.6 m/s (0.84 m)
  EXPECT_NEAR(m.pose().x, 1.02, 0.01);
  EXPECT_NEAR(m.pose().y, 0.0, 1e-9);
  m.set(-0.5, 0.5);  // spin on the spot
  m.advance_to(4'000'000'000);
  EXPECT_NEAR(m.wheel_left_mps(), -0.3, 1e-9);
  m.stop();
  m.advance_to(5'000'000'000);
  EXPECT_EQ(m.wheel_left_mps(), 0.0);
  EXPECT_EQ(m.status().stops, 1u);
}

}  // namespace
}  // namespace fs::robot
