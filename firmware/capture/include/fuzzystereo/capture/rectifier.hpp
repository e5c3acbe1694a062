// Stereo rectification applied by the pipeline to the frames of any backend: from a calibration file
// to row-aligned pairs and the fs::StereoCalib (f, cx, cy, B) of the rectified pair.
//
// Calibration file (OpenCV FileStorage, YAML or XML; docs/capture.md has an example):
//   full calibration (what cv::stereoCalibrate returns):
//     K1, D1, K2, D2   3x3 camera matrices and 1xN / Nx1 distortion vectors (N = 4, 5, 8, 12 or 14);
//                      M1 / M2 (the names of OpenCV's stereo_calib sample) are accepted for K1 / K2
//     R, T             rotation 3x3 and translation 3x1 taking left-camera points to the right camera
//                      (X_right = R X_left + T), T in METRES; the right camera on the right: T.x < 0
//     image_width, image_height   the size the calibration was made at [px]
//   pre-rectified source:
//     rectified: 1 (or true), f [px], B [m], cx, cy [px], optional image_width / image_height
//   optional mounting (copied to StereoCalib): height_m [m], pitch_deg [deg, positive = down]
#pragma once
#include <string>

#include <opencv2/core.hpp>

#include "fuzzystereo/calib.hpp"
#include "fuzzystereo/capture/camera.hpp"

namespace fs::capture {

class Rectifier {
 public:
  // An identity rectifier (frames used as delivered, no calibration known: calib() is invalid).
  Rectifier() = default;
  // Reads and validates `path`; for a full calibration computes cv::stereoRectify (CALIB_ZERO_DISPARITY,
  // so disparity = f*B/Z with no principal-point offset) and the remap tables, once. Throws
  // CaptureError naming the file and the field (missing, wrong size, not finite, implausible).
  static Rectifier from_file(const std::string& path, double alpha = 0.0);
  // From matrices already in memory (same checks; `what` names them in errors).
  static Rectifier from_stereo_calibration(const cv::Mat& K1, const cv::Mat& D1, const cv::Mat& K2, const cv::Mat& D2,
                                           const cv::Mat& R, const cv::Mat& T, cv::Size image_size, double alpha,
                                           const std::string& what = "calibration");
  static Rectifier pre_rectified(const StereoCalib& calib, cv::Size image_size, const std::string& what = "calibration");

  // Rectifies both images of `frame` in place (bilinear remap). Throws CaptureError when the frame
  // size differs from the calibration's image size (naming both sizes, the file and the source).
  void apply(StereoFrame& frame) const;
  // Checks a frame size without remapping (the same error as apply()).
  void check_size(cv::Size frame_size, const std::string& source) const;

  bool remaps() const { return !lmap1_.empty(); }  // false: identity / pre-rectified
  const StereoCalib& calib() const { return calib_; }  // of the rectified pair (invalid for identity)
  cv::Size image_size() const { return size_; }        // 0x0 = any (identity / pre-rectified without size)
  const std::string& file() const { return what_; }
  // Rectification transforms of the full calibration (empty otherwise), for tests and tools.
  const cv::Mat& R1() const { return R1_; }
  const cv::Mat& P1() const { return P1_; }
  const cv::Mat& R2() const { return R2_; }
  const cv::Mat& P2() const { return P2_; }

 private:
  StereoCalib calib_;
  cv::Size size_;
  std::string what_;
  cv::Mat lmap1_, lmap2_, rmap1_, rmap2_;  // CV_16SC2 + CV_16UC1 (fixed-point remap, 1/32 px)
  cv::Mat R1_, P1_, R2_, P2_;
};

}  // namespace fs::capture
