// Camera-pair HAL: one interface (StereoCamera) for every source of synchronised stereo pairs — a
// recorded sequence or dataset (replay), UVC webcams (uvc), two CSI cameras (libcamera) and, wired
// in by the app, the simulator's renderer (sim). Platform code lives only in this folder's backends;
// the pipeline sees StereoFrames. Rectification is NOT done by a backend: the pipeline applies one
// Rectifier (rectifier.hpp) to whatever the backend delivers. See docs/capture.md.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config.hpp"  // fs::ConfigValues (fs_config)
#include "fuzzystereo/calib.hpp"

namespace fs::capture {

// A device or input fault (missing device, no permission, bad source string, unreadable image,
// timeout). what() is one line for the user naming the device/file and what to check.
class CaptureError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One synchronised pair.
struct StereoFrame {
  cv::Mat left, right;        // 8-bit, BGR (CV_8UC3) or grey (CV_8UC1), same size and type
  std::int64_t timestamp_ns = 0;  // capture time of the pair [ns]: live sources use the mean of the
                                  // two sensor timestamps (CLOCK_MONOTONIC / CLOCK_BOOTTIME);
                                  // replay uses timestamps.csv when present, else the injected clock
  std::uint64_t frame_id = 0;     // 0, 1, 2 ... in delivery order for this camera object
  std::string source;             // the source string the camera was opened with
};

// Health counters of a camera since start() (for telemetry / a status command).
struct CaptureStats {
  std::uint64_t pairs = 0;          // pairs delivered by grab()
  std::uint64_t dropped = 0;        // frames dropped without a partner (two-device sources)
  std::int64_t last_offset_ns = 0;  // t_left - t_right of the last pair (two-device sources)
};

// The camera-pair interface. Life cycle: start() -> grab() ... -> stop(); start() after stop()
// starts again. Errors are thrown as CaptureError; grab() returns false only at the end of a finite
// stream (replay without loop), never for a fault.
class StereoCamera {
 public:
  virtual ~StereoCamera() = default;
  // Opens the device(s) / input and starts streaming. Throws CaptureError naming what failed.
  virtual void start() = 0;
  // Blocks until the next synchronised pair and writes it to `out` (true), or returns false at the
  // end of the stream. Live sources throw CaptureError when no pair arrives within timeout_ms.
  virtual bool grab(StereoFrame& out) = 0;
  virtual void stop() = 0;
  // "replay:/data/run1", "uvc:/dev/video0", "libcamera:<id>,<id>" ...
  virtual std::string name() const = 0;
  virtual CaptureStats stats() const { return {}; }
  // The calibration of the rectified pairs as the device itself reports it (the OAK-D rectifies on
  // the device from its factory calibration), valid after start(); std::nullopt for sources that
  // deliver unrectified pairs or do not know (then camera.calibration is needed).
  virtual std::optional<fs::StereoCalib> device_calibration() const { return std::nullopt; }
};

// [camera] section of the config (common/config/schema.toml documents each field and its range).
struct CameraParams {
  int width = 640, height = 480;   // one camera image [px]
  double fps = 30.0;               // live sources [Hz]
  double sync_tolerance_ms = 16.0; // two-device pairing tolerance [ms] (< half a frame period)
  int timeout_ms = 2000;           // live sources: grab() timeout [ms]
  std::string calibration;         // calibration file; empty = use frames as delivered
  double rectify_alpha = 0.0;      // cv::stereoRectify alpha
  double replay_rate_hz = 0.0;     // 0 = as fast as possible
  bool replay_loop = false;
  std::string libcamera_ids;       // "LEFT,RIGHT" or empty
  std::string libcamera_format = "auto";
  std::string oakd_python = "python3";  // oakd: interpreter with depthai >= 3 that runs the bridge
  std::string oakd_bridge;              // oakd: oakd_bridge.py path; empty = installed / source copy
  std::string oakd_bridge_args;         // oakd: extra bridge arguments (tests: "--fake ...")
};
CameraParams camera_params_from(const fs::ConfigValues& v);

// A parsed source string. Grammar (docs/capture.md):
//   replay:DIR                 image sequence or stereo dataset folder
//   uvc:DEV                    one side-by-side device (left half = left camera), DEV = /dev/videoN or N
//   uvc:DEV_LEFT,DEV_RIGHT     two devices
//   libcamera[:ID_LEFT,ID_RIGHT]  two CSI cameras (ids override camera.libcamera_ids)
//   oakd[:DEVICE]              Luxonis OAK-D (rectified mono pairs through oakd_bridge.py and depthai >= 3;
//                              DEVICE = its id (MXID) or name, default the first found)
//   sim[:ARGS]                 the simulator's renderer (provided by the app, see OpenHooks)
enum class SourceKind { Replay, Uvc, Libcamera, Oakd, Sim };
struct SourceSpec {
  SourceKind kind = SourceKind::Replay;
  std::string text;                  // the whole source string as given
  std::vector<std::string> devices;  // replay: {DIR}; uvc: 1 or 2 devices; libcamera: 0 or 2 ids; sim: {ARGS} or {}
};
// Throws CaptureError with the grammar above when `text` is malformed.
SourceSpec parse_source(const std::string& text);
const char* source_kind_name(SourceKind k);

// Left/right image paths of one pair (and its recorded timestamp when the sequence has one).
struct PairPaths {
  std::string left, right;
  std::int64_t timestamp_ns = -1;  // -1 = not recorded
};

// Backends the capture library cannot build itself, supplied by the program:
//  list_dataset: a stereo dataset folder (KITTI / Middlebury, the app's discover_dataset) -> pairs,
//                tried when a replay folder is not an image sequence;
//  sim:          the simulator's renderer wrapped as a StereoCamera.
struct OpenHooks {
  std::function<std::vector<PairPaths>(const std::string& dir)> list_dataset;
  std::function<std::unique_ptr<StereoCamera>(const SourceSpec&, const CameraParams&)> sim;
};

// Builds the backend for `spec` (not started). Throws CaptureError when the backend is not built
// into this program (libcamera, oakd, sim without a hook) or the replay folder has no pairs.
std::unique_ptr<StereoCamera> open_camera(const SourceSpec& spec, const CameraParams& params,
                                          const OpenHooks& hooks = {});

// True when this build has the libcamera backend (pkg-config libcamera found at configure time).
bool libcamera_built();

}  // namespace fs::capture
