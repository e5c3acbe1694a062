// Clocks, front-stop failsafe, watchdogs (sim and wall clock), signal stop flag.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <iostream>
#include <thread>

#include "fuzzystereo/robot/clock.hpp"
#include "fuzzystereo/robot/failsafe.hpp"
#include "fuzzystereo/robot/motors.hpp"

namespace fs::robot {
namespace {

TEST(Clock, SimClockAdvancesOnlyForward) {
  SimClock c(100);
  c.advance(50);
  EXPECT_EQ(c.now_ns(), 150);
  c.sleep_until(1000);  // jumps, no waiting
  EXPECT_EQ(c.now_ns(), 1000);
  c.sleep_until(10);  // in the past: no change
  EXPECT_EQ(c.now_ns(), 1000);
  EXPECT_THROW(c.set(5), std::logic_error);
  WallClock w;
  const auto t0 = w.now_ns();
  w.sleep_until(t0 + 2'000'000);
  EXPECT_GE(w.now_ns() - t0, 2'000'000);
}

TEST(FrontStop, CorridorAndDistance) {
  const Pose2D p{0, 0, 0};
  const double R = 0.15, stop = 0.1;
  EXPECT_TRUE(obstacle_in_front(p, {{{0.44, 0.0}, 0.2, {}}}, R, stop));    // gap 0.09 straight ahead
  EXPECT_FALSE(obstacle_in_front(p, {{{0.46, 0.0}, 0.2, {}}}, R, stop));   // gap 0.11
  EXPECT_TRUE(obstacle_in_front(p, {{{0.40, 0.1}, 0.2, {}}}, R, stop));    // gap ~0.06, in corridor
  EXPECT_FALSE(obstacle_in_front(p, {{{0.60, 0.0}, 0.2, {}}}, R, stop));   // gap 0.25
  EXPECT_FALSE(obstacle_in_front(p, {{{-0.40, 0.0}, 0.2, {}}}, R, stop));  // behind
  EXPECT_FALSE(obstacle_in_front(p, {{{0.20, 0.40}, 0.2, {}}}, R, stop));  // beside, outside corridor
  // heading matters: the same obstacle is ahead when facing +y
  EXPECT_TRUE(obstacle_in_front({0, 0, M_PI / 2}, {{{0.0, 0.40}, 0.2, {}}}, R, stop));
  const BodyTwist c = apply_front_stop({0.4, 0.5}, true, true);
  EXPECT_EQ(c.v, 0.0);
  EXPECT_EQ(c.omega, 0.5);
  EXPECT_EQ(apply_front_stop({0.4, 0.5}, true, false).omega, 0.0);
  EXPECT_EQ(apply_front_stop({0.4, 0.5}, false, false).v, 0.4);
}

TEST(Watchdog, SimClockStallStopsWithin100ms) {
  // 10 Hz frames, timeout 200 ms, loop polled every 10 ms. Frames stop arriving at t_stall (the
  // frame due then never comes). The stop must be commanded <= 100 ms after t_stall, and never
  // while frames still arrive.
  RobotParams rp;
  SimClock clock;
  SimMotors motors(rp);
  std::int64_t stop_at = -1;
  SimWatchdog wd(200'000'000, [&] {
    motors.stop();
    stop_at = clock.now_ns();
  });
  const std::int64_t frame = 100'000'000, poll = 10'000'000, t_stall = 2'000'000'000;
  while (clock.now_ns() < 3'000'000'000) {
    const std::int64_t t = clock.now_ns();
    if (t % frame == 0 && t < t_stall) {
      wd.feed(t);
      motors.set(0.5, 0.5);
    }
    wd.poll(t);
    if (t < t_stall) {
      ASSERT_FALSE(wd.expired()) << "expired at " << t;
    }
    clock.advance(poll);
    motors.advance_to(clock.now_ns());
  }
  ASSERT_GE(stop_at, 0);
  const double latency_ms = static_cast<double>(stop_at - t_stall) * 1e-6;
  std::cout << "[ watchdog ] sim clock: stop commanded " << latency_ms << " ms after the first missed frame ("
            << static_cast<double>(stop_at - (t_stall - frame)) * 1e-6 << " ms after the last frame)\n";
  EXPECT_LE(stop_at - t_stall, 100'000'000);
  EXPECT_GE(stop_at - (t_stall - frame), 200'000'000);  // not before the timeout
  EXPECT_TRUE(motors.status().stopped);
  EXPECT_NEAR(motors.wheel_left_mps(), 0.0, 1e-9);  // and the simulated robot came to rest
  EXPECT_EQ(wd.expiries(), 1);
  wd.feed(clock.now_ns());  // re-armed by the next frame
  EXPECT_FALSE(wd.expired());
}

TEST(Watchdog, WallClockStopsAfterStall) {
  RobotParams rp;
  SimMotors motors(rp);
  std::atomic<std::int64_t> stop_at{0};
  WallClock wc;
  {
    WallWatchdog wd(200'000'000, [&] {
      motors.stop();
      stop_at = wc.now_ns();
    });
    // fed every 50 ms for 400 ms: must not fire
    for (int i = 0; i < 8; ++i) {
      wd.feed();
      motors.set(0.3, 0.3);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    EXPECT_EQ(wd.expiries(), 0);
    EXPECT_FALSE(motors.status().stopped);
    // The last feed happens between these two readings of the same steady clock (under qemu on a
    // loaded machine the thread can be descheduled between feed() and a reading after it, which
    // made a single reading after the feed up to 2.5 ms late and the stop look early).
    const std::int64_t before_feed = wc.now_ns();
    wd.feed();
    const std::int64_t after_feed = wc.now_ns();
    std::this_thread::sleep_for(std::chrono::milliseconds(400));  // stall
    ASSERT_EQ(wd.expiries(), 1);
    EXPECT_TRUE(motors.status().stopped);
    const double after_ms = static_cast<double>(stop_at.load() - after_feed) * 1e-6;
    std::cout << "[ watchdog ] wall clock: stop " << after_ms << " ms after the last frame (timeout 200 ms, latency "
              << after_ms - 200.0 << " ms; feed took " << static_cast<double>(after_feed - before_feed) * 1e-6 << " ms)\n";
    EXPECT_GE(stop_at.load() - before_feed, 200'000'000);  // never before the timeout
    EXPECT_LE(after_ms, 300.0);  // generous: shared CI machine / qemu
  }
}

TEST(Watchdog, SimNeverFedStillExpires) {
  int fired = 0;
  SimWatchdog wd(200, [&] { ++fired; });
  wd.poll(1000);
  wd.poll(1100);
  EXPECT_EQ(fired, 0);
  wd.poll(1200);
  EXPECT_EQ(fired, 1);
  wd.poll(5000);
  EXPECT_EQ(fired, 1);  // once per stall
}

TEST(StopSignal, HandlerOnlySetsTheFlag) {
  clear_stop_request();
  install_stop_signal_handlers();
  EXPECT_FALSE(stop_requested());
  std::raise(SIGTERM);
  EXPECT_TRUE(stop_requested());
  clear_stop_request();
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGINT, SIG_DFL);
}

}  // namespace
}  // namespace fs::robot
