// Used instead of libcamera.cpp when CMake's pkg-config found no libcamera.
#include "backends.hpp"

namespace fs::capture {

bool libcamera_built() { return false; }

std::unique_ptr<StereoCamera> make_libcamera_camera(const SourceSpec&, const CameraParams&) {
  throw CaptureError("libcamera: backend not built: this program was built without libcamera (pkg-config found no "
                     "'libcamera'); install libcamera-dev and rebuild, or use uvc:DEV / replay:DIR");
}

}  // namespace fs::capture
