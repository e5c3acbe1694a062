// `fuzzystereo serve`: the device services of the serial link (fs_link, docs/protocol.md) run
// standalone, with an IDLE stand-in telemetry source: frame ids increase at --rate Hz, there are no
// obstacles, no planner and no motors (telemetry.source says so). Log records are written
// periodically (link.log_period_ms) so logs exist. A snapshot runs the matcher on a built-in
// generated pair (128x96 random texture, background disparity 4 px, a square at 10 px; search
// range capped at 16) and sends its stage dump, so `fuzzyctl snapshot` + `fuzzyctl compare` work
// without a camera. The robot runtime (`fuzzystereo run`) wires the same DeviceServer with its
// real hooks.
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <random>

#include "commands.hpp"
#include "config.hpp"
#include "dump.hpp"
#include "fuzzystereo/link/device_server.hpp"
#include "fuzzystereo/link/log_store.hpp"
#include "fuzzystereo/link/port.hpp"
#include "fuzzystereo/matcher.hpp"
#include "io.hpp"

namespace fs::app {

namespace {

struct ServeOptions {
  std::string link = "pty", state_dir, pty_link;
  int baud = 115200;
  double rate_hz = 10.0;
  int fill_log_kib = 0;
};

// The built-in snapshot pair: seeded random texture; right = left shifted by 4 px, and by 10 px
// inside a centred square (a near obstacle).
void pattern_pair(ImageU8& left, ImageU8& right) {
  const int w = 128, h = 96;
  left = ImageU8(w, h);
  right = ImageU8(w, h);
  std::mt19937 rng(12345);
  std::vector<std::uint8_t> tex(std::size_t(w + 32) * std::size_t(h));
  for (auto& v : tex) v = std::uint8_t(rng() & 0xFF);
  auto T = [&](int x, int y) { return tex[std::size_t(y) * std::size_t(w + 32) + std::size_t(std::clamp(x, 0, w + 31))]; };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) left.at(x, y) = T(x + 16, y);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      // a left pixel at x with disparity d appears in the right image at x - d
      const int xr_bg = x + 4, xr_sq = x + 10;
      const bool sq = xr_sq >= 44 && xr_sq < 84 && y >= 28 && y < 68;
      right.at(x, y) = sq ? T(xr_sq + 16, y) : T(xr_bg + 16, y);
    }
}

link::msg::Telemetry idle_telemetry(std::uint32_t frame, std::uint32_t t_ms, float fps) {
  link::msg::Telemetry t;
  t.frame_id = frame;
  t.t_ms = t_ms;
  t.fps = fps;
  t.source = "idle stand-in (serve: no camera, no planner, no motors)";
  for (int i = 0; i < static_cast<int>(Stage::Count); ++i) t.stages.push_back({stage_name(Stage(i)), 0.0f});
  return t;
}

std::vector<link::SnapshotFile> snapshot(const std::filesystem::path& tmp, MatcherParams params) {
  params.cost.max_disparity = std::min(params.cost.max_disparity, 16);
  ImageU8 left, right;
  pattern_pair(left, right);
  const FisDefinition fis = load_fis_definition("");
  const Matcher m(params, fis);
  const MatchResult r = m.match(left, right);
  std::filesystem::remove_all(tmp);
  write_match_dump(tmp.string(), "builtin:pattern-left", "builtin:pattern-right", params, fis, left, right, r);
  std::vector<link::SnapshotFile> files;
  for (const auto& e : std::filesystem::directory_iterator(tmp)) {
    const std::string t = link::read_file_text(e.path());
    files.push_back({e.path().filename().string(), std::vector<std::uint8_t>(t.begin(), t.end())});
  }
  std::sort(files.begin(), files.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  return files;
}

void run_serve(const ServeOptions& o) {
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGINT);
  sigaddset(&sigs, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);  // before any thread starts: only sigtimedwait below sees them

  const std::filesystem::path state(o.state_dir);
  if (o.fill_log_kib > 0) {  // test aid: one log file of this size for throughput measurements
    link::LogStore fill(state / "logs", std::size_t(o.fill_log_kib) * 1024 + 4096, 1000);
    std::uint32_t frame = 0;
    std::size_t bytes = link::kLogHeaderSize;
    while (bytes < std::size_t(o.fill_log_kib) * 1024) {
      std::vector<std::uint8_t> pl;
      link::Writer w(pl);
      encode(idle_telemetry(frame, frame * 100, 10.0f), w);
      if (!fill.append(frame * 100, link::msg::Telemetry::kId, pl)) throw UserError("cannot write the fill log");
      bytes += pl.size() + 13;
      ++frame;
    }
  }

  std::mutex params_mu;
  MatcherParams params;
  link::DeviceHooks hooks;
  hooks.config_applied = [&](const Config& c) {
    std::lock_guard lock(params_mu);
    params = c.matcher;
  };
  hooks.control = [](link::msg::ControlAction a) {
    std::printf("control: %s (serve has no motors to stop)\n", link::msg::to_string(a));
    std::fflush(stdout);
  };
  hooks.snapshot = [&] {
    MatcherParams p;
    {
      std::lock_guard lock(params_mu);
      p = params;
    }
    return snapshot(state / "snapshot.tmp", p);
  };
  link::ServerOptions so;
  so.link = o.link;
  so.baud = o.baud;
  so.state_dir = o.state_dir;
  so.pty_link_file = o.pty_link;
  so.fw_version = FS_VERSION;
  link::DeviceServer server(hooks, so);
  try {
    server.start();
  } catch (const link::PortError& e) {
    throw UserError(e.what());
  }

  const auto period = std::chrono::duration<double>(1.0 / o.rate_hz);
  const timespec ts{0, long(std::min(period.count(), 0.5) * 1e9)};
  std::uint32_t frame = 0;
  auto last = std::chrono::steady_clock::now();
  for (;;) {
    const int sig = sigtimedwait(&sigs, nullptr, &ts);
    if (sig == SIGINT || sig == SIGTERM) break;
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - last).count();
    last = now;
    if (server.state() != link::msg::RunState::RUNNING) continue;  // paused / e-stop: no frames
    server.publish(idle_telemetry(++frame, server.uptime_ms(), dt > 0 ? float(1.0 / dt) : 0.0f));
  }
  server.stop();
  std::printf("serve: stopped\n");
}

}  // namespace

void add_serve_command(CLI::App& app) {
  auto o = std::make_shared<ServeOptions>();
  CLI::App* c = app.add_subcommand("serve", "Run the serial-link device services standalone (idle stand-in telemetry)");
  c->add_option("--link", o->link, "'pty' (create a pseudo-terminal and print its path) or a serial device, e.g. /dev/ttyAMA0")
      ->default_val("pty");
  c->add_option("--baud", o->baud, "serial baud rate")->default_val(115200);
  c->add_option("--state-dir", o->state_dir, "directory of the config store and the logs")->required();
  c->add_option("--pty-link", o->pty_link, "also write the pty path to this file");
  c->add_option("--rate", o->rate_hz, "stand-in frame rate [Hz]")->default_val(10.0)->check(CLI::Range(0.1, 1000.0));
  c->add_option("--fill-log-kib", o->fill_log_kib, "TEST AID: first write one log file of this size")->check(CLI::Range(0, 1 << 20));
  c->callback([o] { run_serve(*o); });
}

}  // namespace fs::app
