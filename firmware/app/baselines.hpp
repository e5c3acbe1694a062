// OpenCV baselines run beside fuzzystereo in `eval` and `bench`, on the same grey images and the
// same disparity range (0 .. max_disparity-1). Settings are those of OpenCV's
// samples/cpp/stereo_match.cpp (the reference usage of both matchers), except the SGBM block size
// (5 instead of the sample's 3, a common choice for KITTI/Middlebury-sized images):
//   StereoBM    blockSize 9, preFilterCap 31, textureThreshold 10, uniquenessRatio 15,
//               speckleWindowSize 100, speckleRange 32, disp12MaxDiff 1
//   StereoSGBM  MODE_SGBM_3WAY, blockSize 5, P1 = 8*cn*bs^2, P2 = 32*cn*bs^2 (cn = 1, grey input),
//               preFilterCap 63, uniquenessRatio 10, speckleWindowSize 100, speckleRange 32,
//               disp12MaxDiff 1
// Both leave the left band x < max_disparity (and rejected pixels) without an estimate; that is their
// honest output, and the KITTI-style hole filling of metrics.hpp handles it when scoring.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace fs::app {

enum class Baseline { BM, SGBM };

// "bm" / "sgbm".
const char* baseline_name(Baseline b);
// Parses a list of names ("bm", "sgbm"); unknown -> fs::UserError listing the valid names.
std::vector<Baseline> parse_baselines(const std::vector<std::string>& names);

// A configured OpenCV matcher. compute() takes CV_8UC1 images of equal size and returns CV_32FC1
// disparity in px, invalid = -1 (the estimate convention of metrics.hpp).
class BaselineMatcher {
 public:
  BaselineMatcher(Baseline kind, int max_disparity);
  Baseline kind() const { return kind_; }
  // The raw call, timed by eval/bench: CV_16S fixed-point output (disparity * 16).
  cv::Mat compute_raw(const cv::Mat& left_gray, const cv::Mat& right_gray) const;
  static cv::Mat raw_to_float(const cv::Mat& raw16);
  cv::Mat compute(const cv::Mat& left_gray, const cv::Mat& right_gray) const;

 private:
  Baseline kind_;
  cv::Ptr<cv::StereoMatcher> matcher_;
};

}  // namespace fs::app
