// `fuzzystereo capture`: grab N (rectified) pairs from any camera source and write them as an image
// sequence that `replay:DIR` reads back (record on the robot, replay on a desktop):
//   DIR/left/NNNNNN.png, DIR/right/NNNNNN.png   the pairs (PNG, lossless)
//   DIR/timestamps.csv                          frame,timestamp_ns,left,right (one row per pair)
//   DIR/calib.yml                               the rectified pair's calibration (rectified: 1, f, B,
//                                               cx, cy, image size) when a calibration was applied
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <opencv2/core/persistence.hpp>

#include "camera_source.hpp"
#include "commands.hpp"
#include "config.hpp"
#include "fuzzystereo/capture/rectifier.hpp"
#include "io.hpp"

namespace fs::app {

namespace {

struct CaptureOptions {
  std::string source, calib, config, out;
  int count = 0;
};

namespace stdfs = std::filesystem;

void write_rectified_calib(const std::string& path, const StereoCalib& c, cv::Size size) {
  cv::FileStorage f(path, cv::FileStorage::WRITE);
  if (!f.isOpened()) throw UserError("cannot write '" + path + "'");
  f << "rectified" << 1 << "f" << c.focal_px << "B" << c.baseline_m << "cx" << c.cx << "cy" << c.cy
    << "image_width" << size.width << "image_height" << size.height << "height_m" << c.height_m << "pitch_deg"
    << c.pitch_rad * 180.0 / 3.14159265358979323846;
}

void run_capture(const CaptureOptions& o) {
  const Config cfg = load_config(o.config);
  capture::CameraParams p = capture::camera_params_from(cfg.values);
  if (!o.calib.empty()) p.calibration = o.calib;
  const capture::SourceSpec spec = capture::parse_source(o.source);
  if (o.count == 0 && spec.kind != capture::SourceKind::Replay)
    throw UserError("--count N is needed for a live source ('" + o.source + "' never ends)");
  if (o.count == 0 && p.replay_loop) throw UserError("--count N is needed with camera.replay_loop = true");

  // Never overwrite a recording.
  const stdfs::path out(o.out);
  for (const char* sub : {"left", "right"}) {
    std::error_code ec;
    if (stdfs::exists(out / sub, ec) && !stdfs::is_empty(out / sub, ec))
      throw UserError("'" + (out / sub).string() + "' already holds images; choose another --out or remove it");
  }
  const capture::Rectifier rect = p.calibration.empty() ? capture::Rectifier()
                                                        : capture::Rectifier::from_file(p.calibration, p.rectify_alpha);
  // Camera first: a source that cannot open leaves no half-made output folder behind.
  auto cam = capture::open_camera(spec, p, camera_hooks());
  cam->start();
  std::error_code ec;
  stdfs::create_directories(out / "left", ec);
  stdfs::create_directories(out / "right", ec);
  if (ec) throw UserError("cannot create '" + o.out + "': " + ec.message());
  std::ofstream csv(out / "timestamps.csv");
  if (!csv) throw UserError("cannot write '" + (out / "timestamps.csv").string() + "'");
  csv << "frame,timestamp_ns,left,right\n";

  capture::StereoFrame f;
  int n = 0;
  cv::Size size;
  const auto t0 = std::chrono::steady_clock::now();
  while ((o.count == 0 || n < o.count) && cam->grab(f)) {
    rect.apply(f);
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", n);
    write_image((out / "left" / name).string(), f.left);
    write_image((out / "right" / name).string(), f.right);
    csv << n << ',' << f.timestamp_ns << ",left/" << name << ",right/" << name << '\n' << std::flush;
    if (!csv) throw UserError("cannot write '" + (out / "timestamps.csv").string() + "'");
    size = f.left.size();
    ++n;
  }
  cam->stop();
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (rect.calib().valid()) {
    write_rectified_calib((out / "calib.yml").string(), rect.calib(), size);
  } else if (const auto dc = cam->device_calibration()) {  // rectified on the device (oakd)
    write_rectified_calib((out / "calib.yml").string(), *dc, size);
  }
  const capture::CaptureStats st = cam->stats();
  std::printf("captured %d pairs (%dx%d) from %s in %.2f s (%.1f pairs/s, %llu unpaired frames dropped)%s -> %s\n", n,
              size.width, size.height, cam->name().c_str(), s, s > 0 ? n / s : 0.0,
              static_cast<unsigned long long>(st.dropped), rect.remaps() ? ", rectified" : "", o.out.c_str());
  if (n == 0) throw UserError("no pairs captured from '" + o.source + "'");
}

}  // namespace

void add_capture_command(CLI::App& app) {
  auto o = std::make_shared<CaptureOptions>();
  CLI::App* c = app.add_subcommand("capture", "Record (rectified) stereo pairs from a camera source as an image sequence");
  c->add_option("--source", o->source,
                "replay:DIR | uvc:DEV | uvc:DEV_L,DEV_R | libcamera[:ID_L,ID_R] | oakd[:DEVICE] (docs/capture.md)")
      ->required();
  c->add_option("--calib", o->calib, "calibration file (overrides camera.calibration); frames are rectified with it");
  c->add_option("--config", o->config, "TOML config (defaults: common/config/default.toml)");
  c->add_option("--count", o->count, "pairs to record (0 = until a replay source ends)")->check(CLI::NonNegativeNumber);
  c->add_option("--out", o->out, "output directory (left/, right/, timestamps.csv, calib.yml)")->required();
  c->callback([o] {
    try {
      run_capture(*o);
    } catch (const capture::CaptureError& e) {
      throw UserError(e.what());  // device / file fault: one line, exit 2 (main.cpp)
    }
  });
}

}  // namespace fs::app
