// Fakes of the motor I/O interfaces for unit tests (they record what the driver wrote).
#include <algorithm>
#include <cmath>

#include "fuzzystereo/robot/motors.hpp"

namespace fs::robot {

void FakeGpioLines::request_output(int offset, int initial) {
  if (std::find(fail_offsets.begin(), fail_offsets.end(), offset) != fail_offsets.end())
    throw HardwareError("fake: line " + std::to_string(offset) + " busy");
  std::lock_guard<std::mutex> lk(m_);
  values_[offset] = initial ? 1 : 0;
}

void FakeGpioLines::set(int offset, int value) {
  std::lock_guard<std::mutex> lk(m_);
  auto it = values_.find(offset);
  if (it == values_.end()) throw HardwareError("fake: line " + std::to_string(offset) + " set before request");
  it->second = value ? 1 : 0;
  ++writes_[offset];
}

void FakeGpioLines::release_all() {
  std::lock_guard<std::mutex> lk(m_);
  values_.clear();
}

int FakeGpioLines::value(int offset) const {
  std::lock_guard<std::mutex> lk(m_);
  auto it = values_.find(offset);
  return it == values_.end() ? -1 : it->second;
}
bool FakeGpioLines::requested(int offset) const { return value(offset) >= 0; }
std::uint64_t FakeGpioLines::writes(int offset) const {
  std::lock_guard<std::mutex> lk(m_);
  auto it = writes_.find(offset);
  return it == writes_.end() ? 0 : it->second;
}

void FakePwm::set_duty(double d) {
  duty_ = std::isfinite(d) ? std::clamp(d, 0.0, 1.0) : 0.0;
  enabled = true;
  ++writes;
}

}  // namespace fs::robot
