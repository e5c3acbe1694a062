// Factories of the live backends (one .cpp each; libcamera_stub.cpp replaces libcamera.cpp when the
// build has no libcamera). Internal to fs_capture.
#pragma once
#include <memory>

#include "fuzzystereo/capture/camera.hpp"

namespace fs::capture {

std::unique_ptr<StereoCamera> make_uvc_camera(const SourceSpec& spec, const CameraParams& params);
std::unique_ptr<StereoCamera> make_libcamera_camera(const SourceSpec& spec, const CameraParams& params);
// oakd.cpp: the OAK-D through the oakd_bridge.py child process.
std::unique_ptr<StereoCamera> make_oakd_camera(const SourceSpec& spec, const CameraParams& params);

}  // namespace fs::capture
