// Clock HAL: the robot loop reads time and sleeps only through this interface, so the same loop
// runs in real time on the robot (WallClock) and faster than real time in simulation (SimClock).
#pragma once
#include <atomic>
#include <cstdint>

namespace fs::robot {

class Clock {
 public:
  virtual ~Clock() = default;
  // Monotonic time [ns] since an arbitrary epoch.
  virtual std::int64_t now_ns() const = 0;
  // Block until now_ns() >= t_ns (returns at once if already past).
  virtual void sleep_until(std::int64_t t_ns) = 0;
};

// std::chrono::steady_clock.
class WallClock final : public Clock {
 public:
  std::int64_t now_ns() const override;
  void sleep_until(std::int64_t t_ns) override;
};

// Simulated time, advanced explicitly. sleep_until() jumps the clock forward (a single-threaded
// simulation loop therefore never waits). Thread-safe reads.
class SimClock final : public Clock {
 public:
  explicit SimClock(std::int64_t start_ns = 0) : t_(start_ns) {}
  std::int64_t now_ns() const override { return t_.load(std::memory_order_acquire); }
  void sleep_until(std::int64_t t_ns) override;
  void advance(std::int64_t dt_ns);
  void set(std::int64_t t_ns);  // never moves backwards (throws std::logic_error)

 private:
  std::atomic<std::int64_t> t_;
};

constexpr double ns_to_s(std::int64_t ns) { return static_cast<double>(ns) * 1e-9; }
constexpr std::int64_t s_to_ns(double s) { return static_cast<std::int64_t>(s * 1e9 + (s >= 0 ? 0.5 : -0.5)); }

}  // namespace fs::robot
