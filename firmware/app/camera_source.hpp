// The program's camera sources: fs_capture's backends plus those only the app can supply (stereo
// dataset folders via discover_dataset; later the simulator's renderer as the `sim` backend).
#pragma once
#include <memory>
#include <string>

#include "fuzzystereo/capture/camera.hpp"

namespace fs::app {

// Hooks for fs::capture::open_camera: list_dataset = discover_dataset (KITTI / Middlebury layouts).
capture::OpenHooks camera_hooks();

// parse_source + open_camera with camera_hooks(); the camera is not started. Throws CaptureError.
std::unique_ptr<capture::StereoCamera> open_stereo_source(const std::string& source, const capture::CameraParams& p);

}  // namespace fs::app
