// Software PWM: one thread per channel toggles a GPIO line. Used when the hardware PWM overlay is
// not available (e.g. the PWM pins are taken by audio). Timing uses steady_clock absolute
// deadlines so the period does not drift.
#include <algorithm>
#include <chrono>
#include <cmath>

#include "fuzzystereo/robot/motors.hpp"

namespace fs::robot {

SoftPwmChannel::SoftPwmChannel(GpioLines& lines, int offset, double frequency_hz)
    : lines_(lines), offset_(offset), period_ns_(static_cast<std::int64_t>(std::llround(1e9 / frequency_hz))) {
  lines_.request_output(offset_, 0);
  thread_ = std::thread([this] { run(); });
}

SoftPwmChannel::~SoftPwmChannel() {
  quit_ = true;
  thread_.join();
  try {
    lines_.set(offset_, 0);
  } catch (...) {
  }
}

void SoftPwmChannel::set_duty(double duty) { duty_ = std::isfinite(duty) ? std::clamp(duty, 0.0, 1.0) : 0.0; }

std::string SoftPwmChannel::describe() const { return lines_.describe() + " line " + std::to_string(offset_) + " (soft PWM)"; }

void SoftPwmChannel::run() {
  try {
    loop();
  } catch (const std::exception&) {
    // A failing line write (device gone) ends the thread; the motor driver's next stop() writes the
    // direction lines, which fails loudly in the main thread.
    failed_ = true;
  }
}

void SoftPwmChannel::loop() {
  using clk = std::chrono::steady_clock;
  auto t = clk::now();
  int level = -1;
  auto put = [&](int v) {
    if (v != level) {
      lines_.set(offset_, v);
      level = v;
    }
  };
  while (!quit_) {
    const double d = duty_.load();
    const auto on = std::chrono::nanoseconds(static_cast<std::int64_t>(d * static_cast<double>(period_ns_)));
    const auto period = std::chrono::nanoseconds(period_ns_);
    if (d <= 0.0) {
      put(0);
    } else if (d >= 1.0) {
      put(1);
    } else {
      put(1);
      std::this_thread::sleep_until(t + on);
      put(0);
    }
    t += period;
    const auto now = clk::now();
    if (t < now - period) t = now;  // fell behind (scheduler): resync instead of bursting
    std::this_thread::sleep_until(t);
  }
  put(0);
}

}  // namespace fs::robot
