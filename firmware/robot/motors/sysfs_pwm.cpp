// Linux sysfs PWM (Documentation/driver-api/pwm.rst): export the channel, then write period,
// duty_cycle (both in ns, duty_cycle <= period) and enable.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>

#include "fuzzystereo/robot/motors.hpp"

namespace fs::robot {
namespace fsys = std::filesystem;

namespace {
std::string pwm_hint() {
  return "check that /boot/firmware/config.txt has dtoverlay=pwm-2chan,pin=12,func=4,pin2=13,func2=4 (then "
         "reboot), that [motors] pwm_chip/left_pwm_channel/right_pwm_channel match `ls /sys/class/pwm`, and that the "
         "service user may write the PWM files (udev rule, docs/robot.md)";
}
}  // namespace

SysfsPwmChannel::SysfsPwmChannel(const std::string& root, int chip, int channel, double frequency_hz,
                                 int export_wait_ms)
    : period_ns_(static_cast<std::int64_t>(std::llround(1e9 / frequency_hz))) {
  const std::string chip_dir = root + "/pwmchip" + std::to_string(chip);
  dir_ = chip_dir + "/pwm" + std::to_string(channel);
  if (!fsys::is_directory(chip_dir))
    throw HardwareError("motors: no PWM chip at " + chip_dir + " — " + pwm_hint());
  if (!fsys::is_directory(dir_)) {
    std::ofstream ex(chip_dir + "/export");
    if (!ex || !(ex << channel << '\n') || !ex.flush())
      throw HardwareError("motors: cannot write " + chip_dir + "/export to export channel " + std::to_string(channel) +
                          " — " + pwm_hint());
    ex.close();
    // The kernel creates pwm<ch>/ at once, but udev changes its group/mode a moment later.
    const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(export_wait_ms);
    while (!(fsys::is_directory(dir_) && std::ofstream(dir_ + "/period", std::ios::app))) {
      if (std::chrono::steady_clock::now() >= until)
        throw HardwareError("motors: exported channel " + std::to_string(channel) + " but " + dir_ +
                            "/period did not become writable within " + std::to_string(export_wait_ms) + " ms — " +
                            pwm_hint());
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  // duty_cycle must never exceed period: zero it first (the previous period may be shorter).
  write("duty_cycle", "0");
  write("period", std::to_string(period_ns_));
  write("duty_cycle", "0");
  write("enable", "1");
  enabled_ = true;
}

SysfsPwmChannel::~SysfsPwmChannel() {
  try {
    disable();
  } catch (...) {  // destructor: the motors are stopped by HBridgeMotors first; nothing more to do
  }
}

void SysfsPwmChannel::write(const std::string& file, const std::string& value) {
  const std::string path = dir_ + "/" + file;
  std::ofstream f(path);
  if (!f || !(f << value << '\n') || !f.flush())
    throw HardwareError("motors: cannot write '" + value + "' to " + path + " — " + pwm_hint());
}

void SysfsPwmChannel::set_duty(double duty) {
  duty_ = std::isfinite(duty) ? std::clamp(duty, 0.0, 1.0) : 0.0;
  write("duty_cycle", std::to_string(static_cast<std::int64_t>(std::llround(duty_ * static_cast<double>(period_ns_)))));
  if (!enabled_) {
    write("enable", "1");
    enabled_ = true;
  }
}

void SysfsPwmChannel::disable() {
  duty_ = 0;
  write("duty_cycle", "0");
  write("enable", "0");
  enabled_ = false;
}

}  // namespace fs::robot
