// Failsafes: front stop distance, watchdogs, and a signal-safe stop request.
//
// How the app uses them (docs/robot.md "Failsafes"):
//   * install_stop_signal_handlers() once; the handler only sets an atomic flag. The main loop
//     checks stop_requested() every iteration and then calls motors.stop() in the main thread
//     (MotorDriver::stop() takes a mutex and writes files, so it is not async-signal-safe and is
//     never called from the handler). Motor drivers also stop in their destructors.
//   * feed the watchdog after every frame that produced a plan; WallWatchdog stops the motors from
//     its own thread when frames stall (capture hang, matcher overrun); SimWatchdog is polled by
//     the simulated loop.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "fuzzystereo/robot/clock.hpp"
#include "fuzzystereo/robot/geometry.hpp"
#include "fuzzystereo/robot/odometry.hpp"

namespace fs::robot {

// Is any obstacle's surface closer than stop_distance_m in front of the robot? "In front" = the
// centre is ahead of the robot (positive along its heading) inside the corridor swept by the body
// (|lateral offset| < robot radius + obstacle radius). Pass tracked obstacles and this frame's raw
// measurements alike.
bool obstacle_in_front(const Pose2D& pose, const std::vector<CircleObstacle>& obstacles, double robot_radius_m,
                       double stop_distance_m);
// The command with forward motion removed when obstacle_in_front(); omega is kept when
// allow_turning (turning on the spot sweeps no new area for a disc robot), zeroed otherwise.
BodyTwist apply_front_stop(const BodyTwist& cmd, bool obstacle_ahead, bool allow_turning);

// Ground seen ahead (docs/robot.md "Session 32"). The image band where a flat ground from
// the nearest visible row up to band_m forward of the camera appears, in the columns of the robot's
// corridor (half-width robot_radius_m at the band's middle distance): [x0, x1) x [y0, y1). Empty
// (x0 == x1) when the mounting is unknown (height_m <= 0) or no ground that near is in view.
// Ground at forward distance g lies on row cy + f tan(atan(height / g) - pitch).
struct ImageBand {
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  bool empty() const { return x0 >= x1 || y0 >= y1; }
  long pixels() const { return empty() ? 0 : long(x1 - x0) * long(y1 - y0); }
};
ImageBand ground_band_ahead(int width, int height, double focal_px, double cx, double cy, double height_m,
                            double pitch_rad, double robot_radius_m, double band_m);
// Percent of the band's pixels that the detector explained: road (road[i] != 0) or a detected
// obstacle (labels[i] != 0); both row-major with `stride` elements per row. The rest are holes and
// speckle: ground the camera does not see. 100 for an empty band (nothing to judge).
double band_known_pct(const std::uint8_t* road, const std::int32_t* labels, std::size_t stride, const ImageBand& band);

// Simulated-clock watchdog, polled by the loop. on_expire runs once per stall (re-armed by feed()).
class SimWatchdog {
 public:
  SimWatchdog(std::int64_t timeout_ns, std::function<void()> on_expire)
      : timeout_ns_(timeout_ns), on_expire_(std::move(on_expire)) {}
  void feed(std::int64_t now_ns);
  // Returns true while expired. Calls on_expire on the transition into the expired state.
  bool poll(std::int64_t now_ns);
  bool expired() const { return expired_; }
  int expiries() const { return expiries_; }

 private:
  std::int64_t timeout_ns_;
  std::function<void()> on_expire_;
  std::int64_t last_feed_ns_ = 0;
  bool fed_ = false, expired_ = false;
  int expiries_ = 0;
};

// Wall-clock watchdog with its own thread (steady_clock). Armed at construction: if no feed()
// arrives within the timeout, on_expire runs from the watchdog thread (so it must be thread-safe;
// MotorDriver::stop() is). Re-armed by the next feed().
class WallWatchdog {
 public:
  WallWatchdog(std::int64_t timeout_ns, std::function<void()> on_expire);
  ~WallWatchdog();
  WallWatchdog(const WallWatchdog&) = delete;
  WallWatchdog& operator=(const WallWatchdog&) = delete;
  void feed();
  bool expired() const { return expired_.load(); }
  int expiries() const { return expiries_.load(); }

 private:
  void run();
  std::int64_t timeout_ns_;
  std::function<void()> on_expire_;
  std::mutex m_;
  std::condition_variable cv_;
  std::int64_t deadline_ns_;
  bool quit_ = false;
  std::atomic<bool> expired_{false};
  std::atomic<int> expiries_{0};
  std::thread thread_;
};

// SIGINT/SIGTERM set a lock-free flag; nothing else happens in the handler.
void install_stop_signal_handlers();
bool stop_requested();
void request_stop();         // same as the handler (for tests and the app's own error paths)
void clear_stop_request();   // tests only

}  // namespace fs::robot
