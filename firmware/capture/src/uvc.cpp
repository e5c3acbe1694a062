// uvc backend: USB (UVC) cameras through OpenCV's V4L2 capture. Either one side-by-side device (a
// stereo webcam that delivers both images in one frame, left half = left camera) or two devices
// paired by their V4L2 buffer timestamps (TimestampPairer, sync.hpp).
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>

#include <opencv2/videoio.hpp>

#include "backends.hpp"
#include "fuzzystereo/capture/sync.hpp"

namespace fs::capture {

namespace {

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// Opens `dev` ("/dev/videoN" or "N") with V4L2 at w x h @ fps. Every failure names the device and
// what to check.
cv::VideoCapture open_device(const std::string& dev, int w, int h, double fps) {
  const bool numeric = !dev.empty() && dev.find_first_not_of("0123456789") == std::string::npos;
  const std::string path = numeric ? "/dev/video" + dev : dev;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    throw CaptureError("uvc: camera device '" + path + "' does not exist (is the camera plugged in? list devices with "
                       "'v4l2-ctl --list-devices' or 'ls /dev/video*')");
  if (::access(path.c_str(), R_OK | W_OK) != 0)
    throw CaptureError("uvc: no permission to open '" + path + "' (add the user to the 'video' group: "
                       "sudo usermod -aG video $USER, then log in again; check with 'ls -l " + path + "')");
  cv::VideoCapture cap;
  const bool ok = numeric ? cap.open(std::stoi(dev), cv::CAP_V4L2) : cap.open(path, cv::CAP_V4L2);
  if (!ok || !cap.isOpened())
    throw CaptureError("uvc: cannot open '" + path + "' with V4L2 (busy in another program? not a capture node — "
                       "a UVC camera also creates metadata nodes; try 'v4l2-ctl -d " + path + " --all')");
  cap.set(cv::CAP_PROP_FRAME_WIDTH, w);
  cap.set(cv::CAP_PROP_FRAME_HEIGHT, h);
  cap.set(cv::CAP_PROP_FPS, fps);
  cap.set(cv::CAP_PROP_BUFFERSIZE, 2);  // keep latency low: at most one stale buffer
  const int gw = int(cap.get(cv::CAP_PROP_FRAME_WIDTH)), gh = int(cap.get(cv::CAP_PROP_FRAME_HEIGHT));
  if (gw != w || gh != h)
    throw CaptureError("uvc: '" + path + "' does not support " + size_text(w, h) + " (it chose " + size_text(gw, gh) +
                       "); set camera.width / camera.height to a mode from 'v4l2-ctl -d " + path +
                       " --list-formats-ext'" + "");
  return cap;
}

class UvcCamera final : public StereoCamera {
 public:
  UvcCamera(SourceSpec spec, const CameraParams& p) : spec_(std::move(spec)), p_(p) {}

  void start() override {
    stop();
    if (spec_.devices.size() == 1) {
      caps_.push_back(open_device(spec_.devices[0], 2 * p_.width, p_.height, p_.fps));
    } else {
      caps_.push_back(open_device(spec_.devices[0], p_.width, p_.height, p_.fps));
      caps_.push_back(open_device(spec_.devices[1], p_.width, p_.height, p_.fps));
    }
    frame_id_ = 0;
    stats_ = {};
  }

  bool grab(StereoFrame& out) override {
    if (caps_.empty()) throw CaptureError("uvc: grab() before start() on '" + spec_.text + "'");
    const std::int64_t deadline = steady_now_ns() + std::int64_t(p_.timeout_ms) * 1000000;
    if (caps_.size() == 1) {
      cv::Mat sbs;
      if (!caps_[0].read(sbs) || sbs.empty()) fail("no frame from '" + spec_.devices[0] + "'");
      if (sbs.cols != 2 * p_.width || sbs.rows != p_.height)
        fail("'" + spec_.devices[0] + "' delivered " + size_text(sbs.cols, sbs.rows) + ", expected " +
             size_text(2 * p_.width, p_.height) + " side by side");
      out.left = sbs(cv::Rect(0, 0, p_.width, p_.height)).clone();
      out.right = sbs(cv::Rect(p_.width, 0, p_.width, p_.height)).clone();
      out.timestamp_ns = stamp(caps_[0]);
    } else {
      // Two free-running devices: read the side that is behind until the buffer timestamps agree
      // within the tolerance (same rule as TimestampPairer, one frame in flight per side).
      TimestampPairer<cv::Mat> pairer(std::int64_t(p_.sync_tolerance_ms * 1e6), 2);
      std::optional<TimestampPairer<cv::Mat>::Pair> pair;
      bool need_left = true, need_right = true;
      while (!pair) {
        if (steady_now_ns() > deadline)
          fail("no pair within " + std::to_string(p_.timeout_ms) + " ms with timestamps closer than " +
               std::to_string(p_.sync_tolerance_ms) + " ms (camera.sync_tolerance_ms; " +
               std::to_string(pairer.dropped_count()) + " unmatched frames dropped)");
        // grab() both first, then retrieve(): the two exposures are as close as V4L2 allows.
        if (need_left && !caps_[0].grab()) fail("no frame from '" + spec_.devices[0] + "'");
        if (need_right && !caps_[1].grab()) fail("no frame from '" + spec_.devices[1] + "'");
        if (need_left) push(pairer, 0);
        if (need_right) push(pairer, 1);
        pair = pairer.pop();
        need_left = pairer.pending_left() == 0;
        need_right = pairer.pending_right() == 0;
      }
      out.left = std::move(pair->left);
      out.right = std::move(pair->right);
      out.timestamp_ns = (pair->left_ns + pair->right_ns) / 2;
      stats_.dropped += pairer.dropped_count();
      stats_.last_offset_ns = pair->left_ns - pair->right_ns;
    }
    stats_.pairs = frame_id_ + 1;
    out.frame_id = frame_id_++;
    out.source = spec_.text;
    return true;
  }

  void stop() override {
    for (auto& c : caps_) c.release();
    caps_.clear();
  }

  std::string name() const override { return spec_.text; }
  CaptureStats stats() const override { return stats_; }

 private:
  [[noreturn]] void fail(const std::string& why) const { throw CaptureError("uvc: " + spec_.text + ": " + why); }

  // V4L2 buffer timestamp (CAP_PROP_POS_MSEC, CLOCK_MONOTONIC on Linux); the steady clock when the
  // driver gives none.
  static std::int64_t stamp(cv::VideoCapture& c) {
    const double ms = c.get(cv::CAP_PROP_POS_MSEC);
    return (std::isfinite(ms) && ms > 0) ? std::int64_t(ms * 1e6) : steady_now_ns();
  }

  void push(TimestampPairer<cv::Mat>& pairer, int side) {
    cv::Mat m;
    if (!caps_[std::size_t(side)].retrieve(m) || m.empty()) fail("no image from '" + spec_.devices[std::size_t(side)] + "'");
    const std::int64_t ts = stamp(caps_[std::size_t(side)]);
    if (side == 0) pairer.push_left(ts, m); else pairer.push_right(ts, m);
  }

  SourceSpec spec_;
  CameraParams p_;
  std::vector<cv::VideoCapture> caps_;
  std::uint64_t frame_id_ = 0;
  CaptureStats stats_;
};

}  // namespace

std::unique_ptr<StereoCamera> make_uvc_camera(const SourceSpec& spec, const CameraParams& params) {
  return std::make_unique<UvcCamera>(spec, params);
}

}  // namespace fs::capture
