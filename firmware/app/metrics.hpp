// Disparity error metrics with KITTI devkit semantics (devkit_stereo_flow, io_disp.h /
// evaluate_stereo.cpp): invalid estimates are first filled with interpolateBackground(), then every
// pixel with ground truth is scored, so a sparse method is not rewarded for leaving holes.
//
// Conventions (all maps CV_32FC1, same size):
//   estimate:     valid where finite and > 0 (invalid = -1, 0 or NaN; see est_valid);
//   ground truth: valid where finite and > 0 (0 = unknown, as load_ground_truth writes).
#pragma once
#include <cmath>
#include <cstdint>

#include <opencv2/core.hpp>

namespace fs::app {

struct DispMetrics {
  double avg_err = 0.0;   // mean |d_est - d_gt| [px] over GT-valid pixels (after filling)
  double bad2 = 0.0;      // % of GT-valid pixels with error > 2 px
  double bad3 = 0.0;      // % with error > 3 px
  double d1 = 0.0;        // % with error > 3 px AND > 5 % of d_gt (KITTI 2015 D1)
  double density = 0.0;   // % of GT-valid pixels that had an estimate before filling
  std::int64_t gt_pixels = 0;
};

// True for a valid estimate / ground-truth value under the conventions above.
// An estimate of exactly 0 px counts as "no estimate": the KITTI disparity PNG (value = d * 256,
// 0 = invalid) cannot represent it, so this is how the KITTI devkit scores any submitted map, and
// how `match` writes disp_left.png. Applied to every method alike.
inline bool est_valid(float d) { return std::isfinite(d) && d > 0.0f; }
inline bool gt_valid(float d) { return std::isfinite(d) && d > 0.0f; }

// KITTI devkit interpolateBackground(): per row, each run of invalid pixels with valid pixels on
// both sides takes the smaller (background) of the two neighbours; runs touching the left/right
// border take the nearest valid value of the row; then, per column, the invalid pixels above the
// first / below the last valid pixel take that pixel's value (this only reaches rows with no valid
// pixel at all, and only at the top and bottom: an all-invalid row between valid rows stays
// invalid, as in the devkit). Pixels still invalid are scored by evaluate_disparity as d = 0
// (the devkit scores its stored -1; the two differ by 1 px only in that degenerate case).
cv::Mat fill_invalid_kitti(const cv::Mat& disp);

// Metrics of `est` against `gt`. With `area` (CV_8UC1, same size), only the GT-valid pixels where it
// is non-zero are scored (the devkit's evaluation areas: KITTI disp_noc / MiddEval3 mask0nocc give
// "non-occluded"); the filling still uses the whole map, as the devkit's does. Throws
// std::invalid_argument when sizes/types differ.
DispMetrics evaluate_disparity(const cv::Mat& est, const cv::Mat& gt, const cv::Mat& area = cv::Mat());

// The same from a map already filled (filled = fill_invalid_kitti(est)): one fill for several areas.
DispMetrics evaluate_filled(const cv::Mat& est, const cv::Mat& filled, const cv::Mat& gt, const cv::Mat& area = cv::Mat());

}  // namespace fs::app
