#include "fuzzystereo/robot/failsafe.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>

namespace fs::robot {

bool obstacle_in_front(const Pose2D& pose, const std::vector<CircleObstacle>& obstacles, double robot_radius_m,
                       double stop_distance_m) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  for (const CircleObstacle& o : obstacles) {
    const Vec2 d = o.c - pose.pos();
    const double ahead = c * d.x + s * d.y, lateral = -s * d.x + c * d.y;
    if (ahead <= 0) continue;                                   // behind the axle line
    if (std::abs(lateral) >= robot_radius_m + o.r) continue;    // outside the swept corridor
    const double gap = norm(d) - o.r - robot_radius_m;          // surface-to-surface
    if (gap < stop_distance_m) return true;
  }
  return false;
}

BodyTwist apply_front_stop(const BodyTwist& cmd, bool obstacle_ahead, bool allow_turning) {
  if (!obstacle_ahead) return cmd;
  return {std::min(cmd.v, 0.0), allow_turning ? cmd.omega : 0.0};
}

ImageBand ground_band_ahead(int width, int height, double focal_px, double cx, double cy, double height_m,
                            double pitch_rad, double robot_radius_m, double band_m) {
  ImageBand b;
  if (!(height_m > 0.0) || !(focal_px > 0.0) || !(band_m > 0.0) || width <= 0 || height <= 0) return b;
  const double depress_far = std::atan(height_m / band_m) - pitch_rad;  // below the optical axis
  if (depress_far <= -0.5 * M_PI || depress_far >= 0.5 * M_PI) return b;
  const double v_far = cy + focal_px * std::tan(depress_far);
  b.y0 = std::clamp(static_cast<int>(std::ceil(v_far)), 0, height);
  b.y1 = height;
  if (b.y0 >= b.y1) return b;
  // The nearest ground in view (bottom row), for the band's middle distance.
  const double depress_bottom = std::atan((height - 1 - cy) / focal_px) + pitch_rad;
  const double g_near = depress_bottom > 0 ? std::min(band_m, height_m / std::tan(depress_bottom)) : band_m;
  const double half = focal_px * robot_radius_m / (0.5 * (g_near + band_m));
  b.x0 = std::clamp(static_cast<int>(std::floor(cx - half)), 0, width);
  b.x1 = std::clamp(static_cast<int>(std::ceil(cx + half)) + 1, 0, width);
  return b;
}

double band_known_pct(const std::uint8_t* road, const std::int32_t* labels, std::size_t stride, const ImageBand& band) {
  if (band.empty() || road == nullptr || labels == nullptr) return 100.0;
  long known = 0;
  for (int y = band.y0; y < band.y1; ++y) {
    const std::uint8_t* r = road + std::size_t(y) * stride;
    const std::int32_t* l = labels + std::size_t(y) * stride;
    for (int x = band.x0; x < band.x1; ++x) known += (r[x] != 0) | (l[x] != 0);
  }
  return 100.0 * static_cast<double>(known) / static_cast<double>(band.pixels());
}

void SimWatchdog::feed(std::int64_t now_ns) {
  last_feed_ns_ = now_ns;
  fed_ = true;
  expired_ = false;
}

bool SimWatchdog::poll(std::int64_t now_ns) {
  // Never fed counts from the first poll (a loop that never produces a frame must stop too).
  if (!fed_) {
    last_feed_ns_ = now_ns;
    fed_ = true;
  }
  if (!expired_ && now_ns - last_feed_ns_ >= timeout_ns_) {
    expired_ = true;
    ++expiries_;
    if (on_expire_) on_expire_();
  }
  return expired_;
}

namespace {
std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

WallWatchdog::WallWatchdog(std::int64_t timeout_ns, std::function<void()> on_expire)
    : timeout_ns_(timeout_ns), on_expire_(std::move(on_expire)), deadline_ns_(steady_ns() + timeout_ns) {
  thread_ = std::thread([this] { run(); });
}

WallWatchdog::~WallWatchdog() {
  {
    std::lock_guard<std::mutex> lk(m_);
    quit_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void WallWatchdog::feed() {
  {
    std::lock_guard<std::mutex> lk(m_);
    deadline_ns_ = steady_ns() + timeout_ns_;
    expired_ = false;
  }
  cv_.notify_all();
}

void WallWatchdog::run() {
  std::unique_lock<std::mutex> lk(m_);
  while (!quit_) {
    if (expired_) {  // wait for the next feed
      cv_.wait(lk, [&] { return quit_ || !expired_.load(); });
      continue;
    }
    const auto deadline = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(deadline_ns_));
    if (cv_.wait_until(lk, deadline) == std::cv_status::timeout && !quit_ && !expired_ &&
        steady_ns() >= deadline_ns_) {
      expired_ = true;
      ++expiries_;
      lk.unlock();
      if (on_expire_) on_expire_();  // outside the lock: feed() must never wait for the motors
      lk.lock();
    }
  }
}

namespace {
// sig_atomic_t-free: a lock-free std::atomic<bool> is async-signal-safe (static_assert below).
std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free);
extern "C" void fs_robot_stop_handler(int) { g_stop.store(true, std::memory_order_relaxed); }
}  // namespace

void install_stop_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = fs_robot_stop_handler;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}
bool stop_requested() { return g_stop.load(std::memory_order_relaxed); }
void request_stop() { g_stop.store(true, std::memory_order_relaxed); }
void clear_stop_request() { g_stop.store(false, std::memory_order_relaxed); }

}  // namespace fs::robot
