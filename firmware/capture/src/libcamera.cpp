// libcamera backend: two CSI cameras (e.g. two IMX219 on a Raspberry Pi 5), each free-running with
// its own request queue, paired in software by their sensor timestamps (controls::SensorTimestamp,
// start of exposure, CLOCK_BOOTTIME) within camera.sync_tolerance_ms (TimestampPairer, sync.hpp).
// Built only when pkg-config finds libcamera (libcamera_stub.cpp otherwise).
//
// Pixel formats (libcamera names are DRM fourccs, little-endian — the memory byte order is the
// REVERSE of the name): RGB888 = bytes B,G,R (OpenCV BGR as is), XRGB8888 = bytes B,G,R,X,
// YUV420 = planar I420 (Y, then U and V at half resolution).
#include <sys/mman.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <map>
#include <mutex>
#include <sstream>

#include <libcamera/libcamera.h>
#include <opencv2/imgproc.hpp>

#include "backends.hpp"
#include "fuzzystereo/capture/sync.hpp"

namespace fs::capture {

namespace lc = libcamera;

namespace {

const char* kChecks =
    "check: 'rpicam-hello --list-cameras' (or 'libcamera-hello --list-cameras') lists both; /boot/firmware/config.txt has "
    "camera_auto_detect=1 or dtoverlay=<sensor>,cam0 and dtoverlay=<sensor>,cam1; the ribbon cables are seated "
    "(docs/capture.md)";

std::string ids_text(const std::vector<std::shared_ptr<lc::Camera>>& cams) {
  if (cams.empty()) return "none";
  std::string s;
  for (const auto& c : cams) s += (s.empty() ? "'" : ", '") + c->id() + "'";
  return s;
}

struct Mapping {
  void* base = nullptr;
  std::size_t length = 0;
};

// One camera of the pair: configuration, buffers (mmapped once), requests.
struct Side {
  std::shared_ptr<lc::Camera> cam;
  std::unique_ptr<lc::CameraConfiguration> config;
  lc::Stream* stream = nullptr;
  std::unique_ptr<lc::FrameBufferAllocator> alloc;
  std::vector<std::unique_ptr<lc::Request>> requests;
  std::vector<Mapping> mappings;
  std::map<const lc::FrameBuffer*, std::vector<const std::uint8_t*>> planes;  // plane start addresses
  bool acquired = false, started = false;
};

class LibcameraCamera final : public StereoCamera {
 public:
  LibcameraCamera(SourceSpec spec, const CameraParams& p)
      : spec_(std::move(spec)), p_(p), pairer_(std::int64_t(p.sync_tolerance_ms * 1e6), 3) {}
  ~LibcameraCamera() override { stop(); }

  void start() override {
    stop();
    // libcamera logs INFO lines to stderr by default; keep warnings and errors unless the user
    // asked for more with LIBCAMERA_LOG_LEVELS (read once, when libcamera's logger is first used).
    setenv("LIBCAMERA_LOG_LEVELS", "*:WARN", /*overwrite=*/0);
    mgr_ = std::make_unique<lc::CameraManager>();
    if (const int r = mgr_->start(); r != 0)
      fail("cannot start the libcamera CameraManager (error " + std::to_string(r) + ")");
    auto cams = mgr_->cameras();
    std::sort(cams.begin(), cams.end(), [](const auto& a, const auto& b) { return a->id() < b->id(); });
    std::vector<std::string> want = spec_.devices;
    if (want.empty() && !p_.libcamera_ids.empty()) {
      std::istringstream ss(p_.libcamera_ids);
      std::string id;
      while (std::getline(ss, id, ',')) want.push_back(id);
      if (want.size() != 2) fail("camera.libcamera_ids = '" + p_.libcamera_ids + "' must be 'LEFT_ID,RIGHT_ID'");
    }
    if (want.empty()) {
      if (cams.size() < 2)
        fail("found " + std::to_string(cams.size()) + " camera(s) (ids: " + ids_text(cams) +
             "), need 2 for a stereo pair; " + kChecks);
      sides_[0].cam = cams[0];
      sides_[1].cam = cams[1];
    } else {
      for (int s = 0; s < 2; ++s) {
        sides_[s].cam = mgr_->get(want[std::size_t(s)]);
        if (!sides_[s].cam)
          fail(std::string(s == 0 ? "left" : "right") + " camera '" + want[std::size_t(s)] + "' not found; libcamera found " +
               std::to_string(cams.size()) + " camera(s) (ids: " + ids_text(cams) + "); " + kChecks);
      }
    }
    for (int s = 0; s < 2; ++s) setup(s);
    lc::ControlList ctrls(lc::controls::controls);
    const std::int64_t frame_us = std::int64_t(1e6 / p_.fps + 0.5);
    ctrls.set(lc::controls::FrameDurationLimits, lc::Span<const std::int64_t, 2>({frame_us, frame_us}));
    for (int s = 0; s < 2; ++s) {
      Side& sd = sides_[s];
      if (const int r = sd.cam->start(&ctrls); r != 0) fail("cannot start camera '" + sd.cam->id() + "' (error " + std::to_string(r) + ")");
      sd.started = true;
      for (auto& req : sd.requests)
        if (const int r = sd.cam->queueRequest(req.get()); r != 0)
          fail("cannot queue a request on '" + sd.cam->id() + "' (error " + std::to_string(r) + ")");
    }
    frame_id_ = 0;
    std::lock_guard<std::mutex> lock(mu_);
    pairer_ = TimestampPairer<lc::Request*>(std::int64_t(p_.sync_tolerance_ms * 1e6), 3);
    stats_ = {};
  }

  bool grab(StereoFrame& out) override {
    if (!sides_[0].started) fail("grab() before start()");
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(p_.timeout_ms);
    std::optional<TimestampPairer<lc::Request*>::Pair> pair;
    {
      std::unique_lock<std::mutex> lock(mu_);
      for (;;) {
        for (lc::Request* r : pairer_.take_dropped()) requeue(r);
        pair = pairer_.pop();
        for (lc::Request* r : pairer_.take_dropped()) requeue(r);
        if (pair) break;
        if (cv_.wait_until(lock, deadline) == std::cv_status::timeout && !(pair = pairer_.pop())) {
          for (lc::Request* r : pairer_.take_dropped()) requeue(r);
          fail("no synchronised pair within " + std::to_string(p_.timeout_ms) + " ms (pending left " +
               std::to_string(pairer_.pending_left()) + ", right " + std::to_string(pairer_.pending_right()) +
               ", unmatched frames dropped " + std::to_string(pairer_.dropped_count()) +
               "; timestamps closer than camera.sync_tolerance_ms = " + std::to_string(p_.sync_tolerance_ms) + " ms needed)");
        }
        if (pair) break;
      }
    }
    out.left = to_bgr(0, pair->left);
    out.right = to_bgr(1, pair->right);
    requeue(pair->left);
    requeue(pair->right);
    out.timestamp_ns = (pair->left_ns + pair->right_ns) / 2;
    {
      std::lock_guard<std::mutex> lock(mu_);
      stats_ = {frame_id_ + 1, pairer_.dropped_count(), pair->left_ns - pair->right_ns};
    }
    out.frame_id = frame_id_++;
    out.source = spec_.text;
    return true;
  }

  void stop() override {
    for (Side& sd : sides_) {
      if (sd.started) sd.cam->stop();  // completes pending requests as cancelled
      sd.started = false;
      if (sd.cam) sd.cam->requestCompleted.disconnect(this);
    }
    {
      std::lock_guard<std::mutex> lock(mu_);
      pairer_.drain();
      pairer_.take_dropped();
    }
    for (Side& sd : sides_) {
      sd.requests.clear();
      sd.planes.clear();
      for (const Mapping& m : sd.mappings) munmap(m.base, m.length);
      sd.mappings.clear();
      if (sd.alloc && sd.stream) sd.alloc->free(sd.stream);
      sd.alloc.reset();
      sd.config.reset();
      sd.stream = nullptr;
      if (sd.acquired) sd.cam->release();
      sd.acquired = false;
      sd.cam.reset();
    }
    if (mgr_) mgr_->stop();
    mgr_.reset();
  }

  std::string name() const override { return spec_.text; }
  CaptureStats stats() const override {
    std::lock_guard<std::mutex> lock(mu_);
    return stats_;
  }

 private:
  [[noreturn]] void fail(const std::string& why) { throw CaptureError("libcamera: " + why); }

  void setup(int s) {
    Side& sd = sides_[s];
    const std::string id = sd.cam->id();
    if (sd.cam->acquire() != 0) fail("camera '" + id + "' is in use by another process (close rpicam-*/libcamera-* apps)");
    sd.acquired = true;
    std::vector<lc::PixelFormat> formats;
    if (p_.libcamera_format == "auto" || p_.libcamera_format == "RGB888") formats.push_back(lc::formats::RGB888);
    if (p_.libcamera_format == "auto" || p_.libcamera_format == "XRGB8888") formats.push_back(lc::formats::XRGB8888);
    if (p_.libcamera_format == "auto" || p_.libcamera_format == "YUV420") formats.push_back(lc::formats::YUV420);
    std::string tried;
    for (const lc::PixelFormat& f : formats) {
      auto cfg = sd.cam->generateConfiguration({lc::StreamRole::Viewfinder});
      if (!cfg || cfg->size() != 1) fail("camera '" + id + "' gives no viewfinder configuration");
      lc::StreamConfiguration& sc = cfg->at(0);
      sc.pixelFormat = f;
      sc.size = lc::Size(unsigned(p_.width), unsigned(p_.height));
      const auto status = cfg->validate();
      tried += (tried.empty() ? "" : ", ") + f.toString();
      if (status == lc::CameraConfiguration::Invalid || sc.pixelFormat != f) continue;
      if (sc.size.width != unsigned(p_.width) || sc.size.height != unsigned(p_.height))
        fail("camera '" + id + "' cannot deliver " + std::to_string(p_.width) + "x" + std::to_string(p_.height) +
             " (it offers " + sc.size.toString() + "); set camera.width / camera.height");
      sd.config = std::move(cfg);
      break;
    }
    if (!sd.config) fail("camera '" + id + "' accepts none of the formats tried (" + tried + "; camera.libcamera_format)");
    if (sd.cam->configure(sd.config.get()) != 0) fail("cannot configure camera '" + id + "'");
    sd.stream = sd.config->at(0).stream();
    sd.alloc = std::make_unique<lc::FrameBufferAllocator>(sd.cam);
    if (sd.alloc->allocate(sd.stream) < 0) fail("cannot allocate buffers on camera '" + id + "'");
    for (const auto& buf : sd.alloc->buffers(sd.stream)) {
      // Planes may share one dmabuf: map each fd once over the largest extent any plane needs.
      std::map<int, std::size_t> extent;
      for (const auto& pl : buf->planes()) extent[pl.fd.get()] = std::max(extent[pl.fd.get()], std::size_t(pl.offset) + pl.length);
      std::map<int, const std::uint8_t*> base;
      for (const auto& [fd, len] : extent) {
        void* m = mmap(nullptr, len, PROT_READ, MAP_SHARED, fd, 0);
        if (m == MAP_FAILED) fail("cannot mmap a buffer of camera '" + id + "'");
        sd.mappings.push_back({m, len});
        base[fd] = static_cast<const std::uint8_t*>(m);
      }
      auto& pl_ptrs = sd.planes[buf.get()];
      for (const auto& pl : buf->planes()) pl_ptrs.push_back(base[pl.fd.get()] + pl.offset);
      std::unique_ptr<lc::Request> req = sd.cam->createRequest(std::uint64_t(s));
      if (!req || req->addBuffer(sd.stream, buf.get()) != 0) fail("cannot create a request on camera '" + id + "'");
      sd.requests.push_back(std::move(req));
    }
    sd.cam->requestCompleted.connect(this, &LibcameraCamera::on_request_completed);
  }

  // libcamera's thread: queue the completed request for pairing.
  void on_request_completed(lc::Request* req) {
    if (req->status() == lc::Request::RequestCancelled) return;
    std::int64_t ts = 0;
    if (auto t = req->metadata().get(lc::controls::SensorTimestamp)) ts = *t;
    else if (const lc::FrameBuffer* b = req->findBuffer(sides_[req->cookie()].stream)) ts = std::int64_t(b->metadata().timestamp);
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (req->cookie() == 0) pairer_.push_left(ts, req); else pairer_.push_right(ts, req);
    }
    cv_.notify_one();
  }

  void requeue(lc::Request* req) {
    Side& sd = sides_[req->cookie()];
    if (!sd.started) return;
    req->reuse(lc::Request::ReuseBuffers);
    sd.cam->queueRequest(req);
  }

  cv::Mat to_bgr(int s, lc::Request* req) {
    Side& sd = sides_[s];
    const lc::StreamConfiguration& sc = sd.config->at(0);
    const int w = int(sc.size.width), h = int(sc.size.height), stride = int(sc.stride);
    const lc::FrameBuffer* buf = req->findBuffer(sd.stream);
    const auto& pl = sd.planes.at(buf);
    auto* y = const_cast<std::uint8_t*>(pl[0]);
    cv::Mat bgr;
    if (sc.pixelFormat == lc::formats::RGB888) {
      bgr = cv::Mat(h, w, CV_8UC3, y, std::size_t(stride)).clone();  // bytes are B,G,R
    } else if (sc.pixelFormat == lc::formats::XRGB8888) {
      cv::cvtColor(cv::Mat(h, w, CV_8UC4, y, std::size_t(stride)), bgr, cv::COLOR_BGRA2BGR);  // bytes B,G,R,X
    } else {  // YUV420 (I420): repack the padded planes into one contiguous (h*3/2) x w image
      const int cstride = stride / 2;
      const std::uint8_t* u = pl.size() >= 3 ? pl[1] : pl[0] + std::size_t(stride) * std::size_t(h);
      const std::uint8_t* v = pl.size() >= 3 ? pl[2] : u + std::size_t(cstride) * std::size_t(h / 2);
      cv::Mat i420(h * 3 / 2, w, CV_8UC1);
      for (int r = 0; r < h; ++r) std::copy_n(y + std::size_t(r) * std::size_t(stride), w, i420.ptr(r));
      std::uint8_t* dst = i420.ptr(h);
      for (const std::uint8_t* c : {u, v})
        for (int r = 0; r < h / 2; ++r, dst += w / 2) std::copy_n(c + std::size_t(r) * std::size_t(cstride), w / 2, dst);
      cv::cvtColor(i420, bgr, cv::COLOR_YUV2BGR_I420);
    }
    return bgr;
  }

  SourceSpec spec_;
  CameraParams p_;
  std::unique_ptr<lc::CameraManager> mgr_;
  Side sides_[2];
  mutable std::mutex mu_;
  std::condition_variable cv_;
  CaptureStats stats_;
  TimestampPairer<lc::Request*> pairer_;
  std::uint64_t frame_id_ = 0;
};

}  // namespace

bool libcamera_built() { return true; }

std::unique_ptr<StereoCamera> make_libcamera_camera(const SourceSpec& spec, const CameraParams& params) {
  return std::make_unique<LibcameraCamera>(spec, params);
}

}  // namespace fs::capture
