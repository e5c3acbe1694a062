// Source strings, [camera] config and the backend factory.
#include <sstream>

#include "backends.hpp"
#include "fuzzystereo/capture/camera.hpp"
#include "fuzzystereo/capture/replay.hpp"

namespace fs::capture {

namespace {

const char* kGrammar =
    "valid sources: replay:DIR | uvc:DEV | uvc:DEV_LEFT,DEV_RIGHT | libcamera | libcamera:ID_LEFT,ID_RIGHT | oakd | oakd:DEVICE | "
    "sim[:ARGS] (docs/capture.md)";

std::vector<std::string> split_commas(const std::string& s) {
  std::vector<std::string> out;
  std::string cur;
  std::istringstream ss(s);
  while (std::getline(ss, cur, ',')) out.push_back(cur);
  if (!s.empty() && s.back() == ',') out.emplace_back();
  return out;
}

[[noreturn]] void bad(const std::string& text, const std::string& why) {
  throw CaptureError("bad camera source '" + text + "': " + why + "; " + kGrammar);
}

}  // namespace

const char* source_kind_name(SourceKind k) {
  switch (k) {
    case SourceKind::Replay: return "replay";
    case SourceKind::Uvc: return "uvc";
    case SourceKind::Libcamera: return "libcamera";
    case SourceKind::Oakd: return "oakd";
    case SourceKind::Sim: return "sim";
  }
  return "?";
}

SourceSpec parse_source(const std::string& text) {
  if (text.empty()) bad(text, "empty");
  const auto colon = text.find(':');
  const std::string kind = text.substr(0, colon);
  const bool has_arg = colon != std::string::npos;
  const std::string arg = has_arg ? text.substr(colon + 1) : std::string();
  SourceSpec s;
  s.text = text;
  if (kind == "replay") {
    s.kind = SourceKind::Replay;
    if (arg.empty()) bad(text, "replay needs a folder (replay:DIR)");
    s.devices = {arg};
  } else if (kind == "uvc") {
    s.kind = SourceKind::Uvc;
    if (arg.empty()) bad(text, "uvc needs a device (uvc:/dev/video0 or uvc:/dev/video0,/dev/video2)");
    s.devices = split_commas(arg);
    if (s.devices.size() > 2) bad(text, "uvc takes one side-by-side device or two devices, got " + std::to_string(s.devices.size()));
    for (const auto& d : s.devices)
      if (d.empty()) bad(text, "empty device name in the uvc device list");
    if (s.devices.size() == 2 && s.devices[0] == s.devices[1]) bad(text, "left and right are the same device '" + s.devices[0] + "'");
  } else if (kind == "libcamera") {
    s.kind = SourceKind::Libcamera;
    if (has_arg) {
      s.devices = split_commas(arg);
      if (s.devices.size() != 2) bad(text, "libcamera takes two camera ids (libcamera:ID_LEFT,ID_RIGHT) or none");
      for (const auto& d : s.devices)
        if (d.empty()) bad(text, "empty camera id in the libcamera id list");
      if (s.devices[0] == s.devices[1]) bad(text, "left and right are the same camera '" + s.devices[0] + "'");
    }
  } else if (kind == "oakd") {
    s.kind = SourceKind::Oakd;
    if (has_arg) {
      if (arg.empty()) bad(text, "oakd: empty device id (oakd:MXID, or oakd for the first device found)");
      s.devices = {arg};
    }
  } else if (kind == "sim") {
    s.kind = SourceKind::Sim;
    if (has_arg) s.devices = {arg};
  } else {
    bad(text, "unknown kind '" + kind + "'");
  }
  return s;
}

CameraParams camera_params_from(const fs::ConfigValues& v) {
  CameraParams p;
  p.width = v.integer("camera.width");
  p.height = v.integer("camera.height");
  p.fps = v.num("camera.fps");
  p.sync_tolerance_ms = v.num("camera.sync_tolerance_ms");
  p.timeout_ms = v.integer("camera.timeout_ms");
  p.calibration = v.str("camera.calibration");
  p.rectify_alpha = v.num("camera.rectify_alpha");
  p.replay_rate_hz = v.num("camera.replay_rate_hz");
  p.replay_loop = v.flag("camera.replay_loop");
  p.libcamera_ids = v.str("camera.libcamera_ids");
  p.libcamera_format = v.str("camera.libcamera_format");
  p.oakd_python = v.str("camera.oakd_python");
  p.oakd_bridge = v.str("camera.oakd_bridge");
  p.oakd_bridge_args = v.str("camera.oakd_bridge_args");
  return p;
}

std::unique_ptr<StereoCamera> open_camera(const SourceSpec& spec, const CameraParams& params, const OpenHooks& hooks) {
  switch (spec.kind) {
    case SourceKind::Replay: {
      const std::string& dir = spec.devices.at(0);
      std::vector<PairPaths> pairs = discover_image_sequence(dir);
      if (pairs.empty() && hooks.list_dataset) pairs = hooks.list_dataset(dir);
      if (pairs.empty())
        throw CaptureError("replay: no stereo pairs in '" + dir +
                           "' (looked for left/ + right/, image_2/ + image_3/, image_0/ + image_1/, *_left + *_right images" +
                           std::string(hooks.list_dataset ? ", and KITTI / Middlebury dataset layouts" : "") + ")");
      return std::make_unique<ReplayCamera>(spec.text, std::move(pairs),
                                            ReplayOptions{params.replay_rate_hz, params.replay_loop});
    }
    case SourceKind::Uvc: return make_uvc_camera(spec, params);
    case SourceKind::Libcamera: return make_libcamera_camera(spec, params);
    case SourceKind::Oakd: return make_oakd_camera(spec, params);
    case SourceKind::Sim:
      if (!hooks.sim) throw CaptureError("sim: the simulator backend is not linked into this program");
      return hooks.sim(spec, params);
  }
  throw CaptureError("unknown source kind");
}

}  // namespace fs::capture
