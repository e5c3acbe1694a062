// Rectified stereo calibration shared by detection (distance from disparity), the simulator and
// the robot runtime. Camera frame as in OpenCV: X right, Y down, Z forward; the right camera sits
// at +baseline along X. Disparity d [px] of a point at depth Z [m]: d = f * B / Z.
#pragma once

namespace fs {

struct StereoCalib {
  double focal_px = 0.0;    // f [px], rectified (fx == fy)
  double cx = 0.0, cy = 0.0;  // principal point of the rectified left camera [px]
  double baseline_m = 0.0;  // B [m]
  // Mounting on the robot (used by the runtime and the simulator; 0 when unknown).
  double height_m = 0.0;    // optical centre above the ground [m]
  double pitch_rad = 0.0;   // downward tilt of the optical axis [rad], positive = looking down

  bool valid() const { return focal_px > 0.0 && baseline_m > 0.0; }
  // Depth [m] of disparity d [px] (d > 0).
  double depth_of(double disparity_px) const { return focal_px * baseline_m / disparity_px; }
  double disparity_of(double depth_m) const { return focal_px * baseline_m / depth_m; }
};

}  // namespace fs
