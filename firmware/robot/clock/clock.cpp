#include "fuzzystereo/robot/clock.hpp"

#include <chrono>
#include <stdexcept>
#include <thread>

namespace fs::robot {

std::int64_t WallClock::now_ns() const {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void WallClock::sleep_until(std::int64_t t_ns) {
  std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(t_ns)));
}

void SimClock::sleep_until(std::int64_t t_ns) {
  std::int64_t cur = t_.load(std::memory_order_acquire);
  while (cur < t_ns && !t_.compare_exchange_weak(cur, t_ns, std::memory_order_acq_rel)) {
  }
}

void SimClock::advance(std::int64_t dt_ns) {
  if (dt_ns < 0) throw std::logic_error("SimClock::advance: negative step");
  t_.fetch_add(dt_ns, std::memory_order_acq_rel);
}

void SimClock::set(std::int64_t t_ns) {
  if (t_ns < now_ns()) throw std::logic_error("SimClock::set: time would move backwards");
  sleep_until(t_ns);
}

}  // namespace fs::robot
