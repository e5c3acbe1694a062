// oakd backend: a Luxonis OAK-D's rectified mono pairs through oakd_bridge.py (firmware/capture/),
// a child process with depthai >= 3 (a PyPI wheel; the C++ SDK is not packaged for Debian) that
// writes the pairs to a pipe. Stream format: oakd_bridge.py's docstring and docs/formats.md.
// The device rectifies (StereoDepth, factory calibration) and the bridge's hello carries the
// rectified pair's f, cx, cy and baseline: device_calibration(), used by `run` when
// camera.calibration is empty and written by `capture` (docs/capture.md).
//
// The child's stderr goes to an unlinked temporary file, not a pipe: depthai logs there, and an
// undrained pipe would block it; the last lines of that file are the error shown when the child
// fails. The child gets its own process group (a Ctrl-C reaches the firmware, which then stops the
// camera, not the bridge first), an empty signal mask and default SIGINT / SIGTERM (`serve` blocks
// them in its threads) whatever the firmware's own signal set-up.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "backends.hpp"

extern char** environ;

namespace fs::capture {

namespace {

constexpr char kHelloMagic[] = "FSOAKD1\n";  // 8 bytes
constexpr char kPairMagic[] = "FSFR";        // 4 bytes
constexpr std::size_t kPairHeaderBytes = 40;  // struct "<4sIIIqqQ"
// The device boots its firmware before the first pair: allow this long for the hello.
constexpr int kHelloTimeoutMs = 20000;

std::int64_t steady_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::uint32_t le32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
std::uint64_t le64(const unsigned char* p) { return std::uint64_t(le32(p)) | std::uint64_t(le32(p + 4)) << 32; }

// Splits camera.oakd_bridge_args on blanks (no quoting: the arguments are flags and numbers).
std::vector<std::string> split_blanks(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream ss(s);
  std::string w;
  while (ss >> w) out.push_back(w);
  return out;
}

// The bridge script: camera.oakd_bridge when set, else next to the installed binary
// (<prefix>/share/fuzzystereo/oakd_bridge.py), else the source tree's copy.
std::string find_oakd_bridge(const CameraParams& p) {
  namespace stdfs = std::filesystem;
  std::error_code ec;
  if (!p.oakd_bridge.empty()) {
    if (!stdfs::is_regular_file(p.oakd_bridge, ec))
      throw CaptureError("oakd: camera.oakd_bridge = '" + p.oakd_bridge + "' is not a file");
    return p.oakd_bridge;
  }
  std::vector<stdfs::path> tried;
  const stdfs::path exe = stdfs::read_symlink("/proc/self/exe", ec);
  if (!ec) tried.push_back(exe.parent_path().parent_path() / "share" / "fuzzystereo" / "oakd_bridge.py");
#ifdef FS_OAKD_BRIDGE_SOURCE
  tried.emplace_back(FS_OAKD_BRIDGE_SOURCE);
#endif
  std::string list;
  for (const auto& t : tried) {
    if (stdfs::is_regular_file(t, ec)) return t.string();
    list += (list.empty() ? "" : ", ") + t.string();
  }
  throw CaptureError("oakd: bridge script oakd_bridge.py not found (looked in: " + list +
                     "); set camera.oakd_bridge to its path");
}

}  // namespace

class OakdCamera final : public StereoCamera {
 public:
  OakdCamera(SourceSpec spec, const CameraParams& p) : spec_(std::move(spec)), p_(p) {}
  ~OakdCamera() override { stop(); }

  void start() override {
    stop();
    const std::string bridge = find_oakd_bridge(p_);
    std::vector<std::string> args = {p_.oakd_python, bridge, "--width", std::to_string(p_.width), "--height",
                                     std::to_string(p_.height), "--fps", std::to_string(p_.fps)};
    if (!spec_.devices.empty()) {
      args.emplace_back("--device");
      args.push_back(spec_.devices[0]);
    }
    for (auto& a : split_blanks(p_.oakd_bridge_args)) args.push_back(std::move(a));

    char tmpl[] = "/tmp/fuzzystereo_oakd_XXXXXX";
    const int err_fd = ::mkostemp(tmpl, O_CLOEXEC);
    if (err_fd < 0) throw CaptureError(std::string("oakd: cannot create a temporary file: ") + std::strerror(errno));
    int out_pipe[2];
    if (::pipe2(out_pipe, O_CLOEXEC) != 0) {  // the firmware's other descriptors stay out of the child
      ::close(err_fd);
      throw CaptureError(std::string("oakd: pipe() failed: ") + std::strerror(errno));
    }
    ::unlink(tmpl);  // the file lives while err_fd_ and the child's stderr are open
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, out_pipe[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&fa, err_fd, STDERR_FILENO);
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    sigset_t none, defaults;
    sigemptyset(&none);
    sigemptyset(&defaults);
    sigaddset(&defaults, SIGINT);
    sigaddset(&defaults, SIGTERM);
    sigaddset(&defaults, SIGPIPE);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setsigdefault(&attr, &defaults);
    posix_spawnattr_setpgroup(&attr, 0);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETPGROUP);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_t pid = -1;
    const int rc = ::posix_spawnp(&pid, args[0].c_str(), &fa, &attr, argv.data(), environ);
    posix_spawnattr_destroy(&attr);
    posix_spawn_file_actions_destroy(&fa);
    ::close(out_pipe[1]);
    if (rc != 0) {
      ::close(out_pipe[0]);
      ::close(err_fd);
      throw CaptureError("oakd: cannot start '" + p_.oakd_python + "' (" + std::strerror(rc) +
                         "); set camera.oakd_python to a Python 3 with depthai >= 3 (docs/capture.md)");
    }
    pid_ = pid;
    fd_ = out_pipe[0];
    err_fd_ = err_fd;
    reaped_ = false;
    {
      std::lock_guard<std::mutex> lock(mu_);
      stats_ = {};
      error_.clear();
      have_pair_ = false;
    }
    stop_ = false;
    next_id_ = 0;
    have_seq_ = false;

    // The hello, synchronously: start() fails with the bridge's reason (no depthai, no device ...).
    char magic[8];
    read_exact(magic, sizeof magic, kHelloTimeoutMs, "the bridge's hello");
    if (std::memcmp(magic, kHelloMagic, 8) != 0) fail("the bridge sent no hello (is camera.oakd_bridge oakd_bridge.py?)");
    std::string line;
    for (char c = 0;;) {
      read_exact(&c, 1, kHelloTimeoutMs, "the bridge's hello");
      if (c == '\n') break;
      line.push_back(c);
      if (line.size() > 4096) fail("the bridge's hello line is longer than 4096 bytes");
    }
    calib_.reset();
    device_.clear();
    try {
      const auto j = nlohmann::json::parse(line);
      auto num = [&](const char* k) { return j.contains(k) && j[k].is_number() ? j[k].get<double>() : 0.0; };
      StereoCalib c;
      c.focal_px = num("f_px");
      c.baseline_m = num("baseline_m");
      c.cx = num("cx");
      c.cy = num("cy");
      if (c.valid()) calib_ = c;
      if (j.contains("device") && j["device"].is_string()) {
        device_ = j["device"].get<std::string>();
        if (j.contains("depthai") && j["depthai"].is_string()) device_ += ", depthai " + j["depthai"].get<std::string>();
      }
    } catch (const nlohmann::json::exception& e) {
      fail(std::string("the bridge's hello is not JSON (") + e.what() + ")");
    }
    // Then the pairs, on a reader thread that keeps only the newest: the OAK-D streams at
    // camera.fps whatever the loop's rate, and a robot must act on the latest pair, not on a queue
    // of old ones (a pair replaced before grab() counts as dropped).
    reader_ = std::thread([this] { read_loop(); });
  }

  std::optional<StereoCalib> device_calibration() const override { return calib_; }

  bool grab(StereoFrame& out) override {
    if (fd_ < 0) throw CaptureError("oakd: grab() before start()");
    std::unique_lock<std::mutex> lock(mu_);
    const bool ready = cv_.wait_for(lock, std::chrono::milliseconds(p_.timeout_ms),
                                    [&] { return have_pair_ || !error_.empty(); });
    if (have_pair_) {  // a pair that arrived before a failure is still delivered
      out = std::move(pair_);
      have_pair_ = false;
      out.frame_id = next_id_++;
      out.source = spec_.text;
      ++stats_.pairs;
      return true;
    }
    if (!ready) {
      lock.unlock();
      fail("no pair from the bridge for " + std::to_string(p_.timeout_ms) +
               " ms (camera.timeout_ms; device unplugged or hung?)",
           true);
    }
    throw CaptureError(error_);
  }

  void stop() override {
    stop_ = true;
    if (reader_.joinable()) reader_.join();  // it polls in 100 ms slices and checks stop_
    if (fd_ >= 0) ::close(fd_);  // a bridge still writing gets EPIPE
    fd_ = -1;
    if (pid_ > 0 && !reaped_) {  // (a reaped pid may belong to another process by now)
      ::kill(pid_, SIGTERM);
      int status = 0;
      const std::int64_t t0 = steady_ms();
      while (::waitpid(pid_, &status, WNOHANG) == 0) {
        if (steady_ms() - t0 > 2000) {
          ::kill(pid_, SIGKILL);
          ::waitpid(pid_, &status, 0);
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
    }
    pid_ = -1;
    reaped_ = false;
    if (err_fd_ >= 0) ::close(err_fd_);
    err_fd_ = -1;
  }

  // "oakd (device 14442C10D13EABCE00, depthai 3.12.0)" once started: which device the log is about.
  std::string name() const override { return device_.empty() ? spec_.text : spec_.text + " (device " + device_ + ")"; }
  CaptureStats stats() const override {
    std::lock_guard<std::mutex> lock(mu_);
    return stats_;
  }

 private:
  // Reader thread: pair after pair into the one-pair mailbox; the first failure ends it, with the
  // message grab() then throws.
  void read_loop() {
    try {
      for (;;) {
        unsigned char h[kPairHeaderBytes];
        if (!read_exact(h, sizeof h, -1, "a pair")) return;  // stop()
        if (std::memcmp(h, kPairMagic, 4) != 0) fail("bad pair header in the bridge stream");
        const std::uint32_t w = le32(h + 4), ht = le32(h + 8), ch = le32(h + 12);
        const auto tl = static_cast<std::int64_t>(le64(h + 16)), tr = static_cast<std::int64_t>(le64(h + 24));
        const std::uint64_t seq = le64(h + 32);
        if (int(w) != p_.width || int(ht) != p_.height || (ch != 1 && ch != 3))
          fail("the bridge sent a " + std::to_string(w) + "x" + std::to_string(ht) + "x" + std::to_string(ch) +
               " pair, expected " + std::to_string(p_.width) + "x" + std::to_string(p_.height) + " (1 or 3 channels)");
        const int type = ch == 1 ? CV_8UC1 : CV_8UC3;
        StereoFrame f;
        f.left.create(int(ht), int(w), type);
        f.right.create(int(ht), int(w), type);
        if (!read_exact(f.left.data, f.left.total() * f.left.elemSize(), -1, "a pair")) return;
        if (!read_exact(f.right.data, f.right.total() * f.right.elemSize(), -1, "a pair")) return;
        f.timestamp_ns = tl / 2 + tr / 2 + (tl % 2 + tr % 2) / 2;
        std::lock_guard<std::mutex> lock(mu_);
        if (have_seq_ && seq > last_seq_ + 1) stats_.dropped += seq - last_seq_ - 1;  // lost before the pipe
        if (have_pair_) ++stats_.dropped;                                              // replaced unread
        have_seq_ = true;
        last_seq_ = seq;
        stats_.last_offset_ns = tl - tr;
        pair_ = std::move(f);
        have_pair_ = true;
        cv_.notify_all();
      }
    } catch (const CaptureError& e) {
      std::lock_guard<std::mutex> lock(mu_);
      error_ = e.what();
      cv_.notify_all();
    }
  }

  // Reads exactly n bytes. timeout_ms >= 0: within that time, else CaptureError; < 0: no limit, but
  // false when stop() is asked for. The bridge's end -> CaptureError with its exit code and last
  // stderr line.
  bool read_exact(void* dst, std::size_t n, int timeout_ms, const char* what) {
    auto* p = static_cast<unsigned char*>(dst);
    const std::int64_t deadline = timeout_ms >= 0 ? steady_ms() + timeout_ms : 0;
    while (n > 0) {
      if (stop_) return false;
      int slice = 100;
      if (timeout_ms >= 0) {
        const std::int64_t left_ms = deadline - steady_ms();
        if (left_ms <= 0)
          fail("no data from the bridge for " + std::to_string(timeout_ms) + " ms while waiting for " + what +
                   " (camera.timeout_ms; device unplugged or hung?)",
               true);
        slice = int(std::min<std::int64_t>(left_ms, 100));
      }
      pollfd pfd{fd_, POLLIN, 0};
      const int pr = ::poll(&pfd, 1, slice);
      if (pr < 0) {
        if (errno == EINTR) continue;
        fail(std::string("poll() failed: ") + std::strerror(errno));
      }
      if (pr == 0) continue;
      const ssize_t r = ::read(fd_, p, n);
      if (r < 0) {
        if (errno == EINTR || errno == EAGAIN) continue;
        fail(std::string("read() failed: ") + std::strerror(errno));
      }
      if (r == 0) {
        if (stop_) return false;
        fail(std::string("the bridge ended while sending ") + what);
      }
      p += r;
      n -= std::size_t(r);
    }
    return true;
  }

  // child_may_live: a timeout (the bridge may be hung, stop() ends it); otherwise the bridge is
  // expected to exit, and its exit code is reported when it does within 1 s.
  [[noreturn]] void fail(const std::string& why, bool child_may_live = false) {
    std::string msg = "oakd: " + why;
    if (pid_ > 0 && !child_may_live) {
      for (int i = 0; i < 50 && !stop_; ++i) {
        int status = 0;
        if (::waitpid(pid_, &status, WNOHANG) == pid_) {
          if (WIFEXITED(status)) msg += " (bridge exit code " + std::to_string(WEXITSTATUS(status)) + ")";
          if (WIFSIGNALED(status)) msg += " (bridge killed by signal " + std::to_string(WTERMSIG(status)) + ")";
          reaped_ = true;
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
    const std::string tail = stderr_tail();
    if (!tail.empty()) msg += ": " + tail;
    throw CaptureError(msg);
  }

  // The bridge's own error lines ("oakd_bridge: ...") if any, else its last stderr line.
  std::string stderr_tail() const {
    if (err_fd_ < 0) return {};
    std::string text;
    char buf[4096];
    for (off_t off = 0;;) {  // pread: the child may still be writing at its own offset
      const ssize_t r = ::pread(err_fd_, buf, sizeof buf, off);
      if (r <= 0) break;
      text.append(buf, std::size_t(r));
      off += r;
      if (text.size() > (1u << 20)) text.erase(0, text.size() - 65536);  // a chatty child: keep the end
    }
    std::istringstream f(text);
    std::string line, last, ours;
    while (std::getline(f, line)) {
      if (line.empty()) continue;
      last = line;
      if (line.rfind("oakd_bridge:", 0) == 0 || line.rfind("usage:", 0) == 0 || line.find("error:") != std::string::npos)
        ours = line;
    }
    return ours.empty() ? last : ours;
  }

  SourceSpec spec_;
  CameraParams p_;
  pid_t pid_ = -1;
  bool reaped_ = false;  // fail() collected the exit status (stop() must not wait for it)
  int fd_ = -1;          // the bridge's stdout
  int err_fd_ = -1;      // its stderr (unlinked temporary file)
  std::string device_;  // "ID, depthai VERSION" from the hello (name())
  std::optional<StereoCalib> calib_;  // from the hello: f, B, cx, cy of the rectified pair
  std::thread reader_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mu_;  // guards the mailbox, error_ and stats_
  std::condition_variable cv_;
  StereoFrame pair_;  // the newest pair not yet delivered (valid when have_pair_)
  bool have_pair_ = false;
  std::string error_;  // the reader's failure, thrown by grab()
  CaptureStats stats_;
  std::uint64_t next_id_ = 0, last_seq_ = 0;
  bool have_seq_ = false;
};

std::unique_ptr<StereoCamera> make_oakd_camera(const SourceSpec& spec, const CameraParams& params) {
  return std::make_unique<OakdCamera>(spec, params);
}

}  // namespace fs::capture
