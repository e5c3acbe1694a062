// Clocks, front-stop failsafe, watchdogs (sim and wall clock), signal stop flag.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <iostream>
#include <thread>
#include <vector>

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

// The ground band ahead of the suite's robot camera (320 x 180, f 134.26 px, 0.40 m high, 5 deg down,
// robot radius 0.15 m, band up to 1.0 m): its rows are where a flat ground from the bottom row's distance
// to 1.0 m projects, checked against a pinhole projection of ground points; its columns the corridor.
TEST(GroundSeenAhead, BandIsTheCorridorGroundUpToTheBandDistance) {
  const int W = 320, H = 180;
  const double f = 134.26, cx = 159.5, cy = 89.5, Hc = 0.40, pitch = 5.0 * M_PI / 180.0, R = 0.15;
  const ImageBand b = ground_band_ahead(W, H, f, cx, cy, Hc, pitch, R, 1.0);
  ASSERT_FALSE(b.empty());
  // project a ground point (forward g, lateral l) into the pitched camera
  auto project = [&](double g, double l, double& u, double& v) {
    const double zc = g * std::cos(pitch) + Hc * std::sin(pitch);  // along the optical axis
    const double yc = Hc * std::cos(pitch) - g * std::sin(pitch);  // down in the image
    u = cx - f * l / zc;
    v = cy + f * yc / zc;
  };
  double u, v;
  project(1.0, 0.0, u, v);
  EXPECT_EQ(b.y0, static_cast<int>(std::ceil(v)));  // the first row at or below the ground 1.0 m ahead
  project(1.02, 0.0, u, v);
  EXPECT_LT(v, b.y0);  // ground beyond the band lies above it
  EXPECT_EQ(b.y1, H);
  // the corridor: +-R at the band's middle distance, symmetric about cx
  project(0.9, 0.0, u, v);
  EXPECT_GT(v, b.y0);
  EXPECT_NEAR(0.5 * (b.x0 + b.x1 - 1), cx, 1.0);
  const double g_near = Hc / std::tan(std::atan((H - 1 - cy) / f) + pitch);  // the bottom row's ground
  EXPECT_NEAR(g_near, 0.50, 0.01);
  const double half = f * R / (0.5 * (g_near + 1.0));
  EXPECT_NEAR(b.x1 - b.x0, 2.0 * half + 1.0, 2.0);
  // unknown mounting, or a band that ends before the nearest ground in view: nothing to judge
  EXPECT_TRUE(ground_band_ahead(W, H, f, cx, cy, 0.0, pitch, R, 1.0).empty());
  EXPECT_TRUE(ground_band_ahead(W, H, f, cx, cy, Hc, pitch, R, 0.3).empty());
  // looking up (pitch -60 deg): no ground in view at all
  EXPECT_TRUE(ground_band_ahead(W, H, f, cx, cy, Hc, -60.0 * M_PI / 180.0, R, 1.0).empty());
}

TEST(GroundSeenAhead, KnownShareCountsRoadOrObstaclePixelsInsideTheBand) {
  const int W = 8, H = 6;
  std::vector<std::uint8_t> road(W * H, 0);
  std::vector<std::int32_t> labels(W * H, 0);
  ImageBand b;
  b.x0 = 2; b.x1 = 6; b.y0 = 3; b.y1 = 6;  // 4 x 3 = 12 pixels
  EXPECT_EQ(b.pixels(), 12);
  EXPECT_DOUBLE_EQ(band_known_pct(road.data(), labels.data(), W, b), 0.0);
  for (int x = 0; x < W; ++x) road[std::size_t(5 * W + x)] = 1;  // the bottom row is road: 4 of 12 inside
  labels[std::size_t(3 * W + 2)] = 7;                             // an obstacle pixel inside
  labels[std::size_t(4 * W + 2)] = 7;
  road[std::size_t(4 * W + 2)] = 1;                                // road and obstacle: counted once
  labels[std::size_t(0 * W + 0)] = 3;                              // outside the band: not counted
  road[std::size_t(3 * W + 7)] = 1;                                // outside (x = 7)
  EXPECT_DOUBLE_EQ(band_known_pct(road.data(), labels.data(), W, b), 100.0 * 6.0 / 12.0);
  EXPECT_DOUBLE_EQ(band_known_pct(road.data(), labels.data(), W, ImageBand{}), 100.0);  // empty band
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
