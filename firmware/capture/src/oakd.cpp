// oakd backend: a Luxonis OAK-D's rectified mono pairs through oakd_bridge.py (firmware/capture/),
// a child process with depthai >= 3 (a PyPI wheel; the C++ SDK is not packaged for Debian) that
// writes the pairs to a pipe. Stream format: oakd_bridge.py's docstring and docs/formats.md.
// The device rectifies (StereoDepth, factory calibration), so camera.calibration should hold the
// pre-rectified calibration that `oakd_bridge.py --write-calib FILE` writes (docs/capture.md).
//
// The child's stderr goes to a temporary file, not a pipe: depthai logs there, and an undrained
// pipe would block it; the last lines of that file are the error shown when the child fails.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
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

}  // namespace

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
    err_path_ = tmpl;
    int out_pipe[2];
    if (::pipe2(out_pipe, O_CLOEXEC) != 0) {  // the firmware's other descriptors stay out of the child
      ::close(err_fd);
      throw CaptureError(std::string("oakd: pipe() failed: ") + std::strerror(errno));
    }
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, out_pipe[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&fa, err_fd, STDERR_FILENO);
    posix_spawn_file_actions_addclose(&fa, out_pipe[0]);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_t pid = -1;
    const int rc = ::posix_spawnp(&pid, args[0].c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    ::close(out_pipe[1]);
    ::close(err_fd);
    if (rc != 0) {
      ::close(out_pipe[0]);
      std::filesystem::remove(err_path_);
      err_path_.clear();
      throw CaptureError("oakd: cannot start '" + p_.oakd_python + "' (" + std::strerror(rc) +
                         "); set camera.oakd_python to a Python 3 with depthai >= 3 (docs/capture.md)");
    }
    pid_ = pid;
    fd_ = out_pipe[0];
    stats_ = {};
    next_id_ = 0;
    have_seq_ = false;

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
    hello_ = line;
    calib_.reset();
    try {
      const auto j = nlohmann::json::parse(line);
      auto num = [&](const char* k) { return j.contains(k) && j[k].is_number() ? j[k].get<double>() : 0.0; };
      StereoCalib c;
      c.focal_px = num("f_px");
      c.baseline_m = num("baseline_m");
      c.cx = num("cx");
      c.cy = num("cy");
      if (c.valid()) calib_ = c;
    } catch (const nlohmann::json::exception& e) {
      fail(std::string("the bridge's hello is not JSON (") + e.what() + ")");
    }
  }

  std::optional<StereoCalib> device_calibration() const override { return calib_; }

  bool grab(StereoFrame& out) override {
    if (fd_ < 0) throw CaptureError("oakd: grab() before start()");
    unsigned char h[kPairHeaderBytes];
    read_exact(h, sizeof h, p_.timeout_ms, "a pair");
    if (std::memcmp(h, kPairMagic, 4) != 0) fail("bad pair header in the bridge stream");
    const std::uint32_t w = le32(h + 4), ht = le32(h + 8), ch = le32(h + 12);
    const auto tl = static_cast<std::int64_t>(le64(h + 16)), tr = static_cast<std::int64_t>(le64(h + 24));
    const std::uint64_t seq = le64(h + 32);
    if (int(w) != p_.width || int(ht) != p_.height || (ch != 1 && ch != 3))
      fail("the bridge sent a " + std::to_string(w) + "x" + std::to_string(ht) + "x" + std::to_string(ch) +
           " pair, expected " + std::to_string(p_.width) + "x" + std::to_string(p_.height) + " (1 or 3 channels)");
    const int type = ch == 1 ? CV_8UC1 : CV_8UC3;
    cv::Mat left(int(ht), int(w), type), right(int(ht), int(w), type);
    read_exact(left.data, left.total() * left.elemSize(), p_.timeout_ms, "a pair");
    read_exact(right.data, right.total() * right.elemSize(), p_.timeout_ms, "a pair");
    if (have_seq_ && seq > last_seq_ + 1) stats_.dropped += seq - last_seq_ - 1;
    have_seq_ = true;
    last_seq_ = seq;
    out.left = std::move(left);
    out.right = std::move(right);
    out.timestamp_ns = tl / 2 + tr / 2 + (tl % 2 + tr % 2) / 2;
    out.frame_id = next_id_++;
    out.source = spec_.text;
    ++stats_.pairs;
    stats_.last_offset_ns = tl - tr;
    return true;
  }

  void stop() override {
    if (fd_ >= 0) ::close(fd_);  // the bridge's next write fails with EPIPE and it exits
    fd_ = -1;
    if (pid_ > 0) {
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
      pid_ = -1;
    }
    if (!err_path_.empty()) {
      std::error_code ec;
      std::filesystem::remove(err_path_, ec);
      err_path_.clear();
    }
  }

  std::string name() const override { return spec_.text; }
  CaptureStats stats() const override { return stats_; }
  // The bridge's hello JSON (device id, depthai version, rectified f / baseline): for the log.
  const std::string& hello() const { return hello_; }

 private:
  // Reads exactly n bytes within timeout_ms; the bridge's end or a timeout -> CaptureError with the
  // bridge's last stderr lines.
  void read_exact(void* dst, std::size_t n, int timeout_ms, const char* what) {
    auto* p = static_cast<unsigned char*>(dst);
    const std::int64_t deadline = steady_ms() + timeout_ms;
    while (n > 0) {
      const std::int64_t left_ms = deadline - steady_ms();
      if (left_ms <= 0)
        fail("no data from the bridge for " + std::to_string(timeout_ms) + " ms while waiting for " + what +
                 " (camera.timeout_ms; device unplugged or hung?)",
             true);
      pollfd pfd{fd_, POLLIN, 0};
      const int pr = ::poll(&pfd, 1, int(std::min<std::int64_t>(left_ms, 1000)));
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
      if (r == 0) fail(std::string("the bridge ended while sending ") + what);
      p += r;
      n -= std::size_t(r);
    }
  }

  // child_may_live: a timeout (the bridge may be hung, stop() ends it); otherwise the bridge is
  // expected to exit, and its exit code is reported when it does within 1 s.
  [[noreturn]] void fail(const std::string& why, bool child_may_live = false) {
    std::string msg = "oakd: " + why;
    if (pid_ > 0 && !child_may_live) {
      for (int i = 0; i < 50; ++i) {
        int status = 0;
        if (::waitpid(pid_, &status, WNOHANG) == pid_) {
          if (WIFEXITED(status)) msg += " (bridge exit code " + std::to_string(WEXITSTATUS(status)) + ")";
          if (WIFSIGNALED(status)) msg += " (bridge killed by signal " + std::to_string(WTERMSIG(status)) + ")";
          pid_ = -1;
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
    if (err_path_.empty()) return {};
    std::ifstream f(err_path_);
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
  int fd_ = -1;
  std::string err_path_, hello_;
  std::optional<StereoCalib> calib_;  // from the hello: f, B, cx, cy of the rectified pair
  CaptureStats stats_;
  std::uint64_t next_id_ = 0, last_seq_ = 0;
  bool have_seq_ = false;
};

std::unique_ptr<StereoCamera> make_oakd_camera(const SourceSpec& spec, const CameraParams& params) {
  return std::make_unique<OakdCamera>(spec, params);
}

}  // namespace fs::capture
