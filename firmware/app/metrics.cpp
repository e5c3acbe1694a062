// KITTI-devkit style disparity metrics (see metrics.hpp). The filling follows the devkit's
// DisparityImage::interpolateBackground() line by line; only the storage differs (invalid = any
// value failing est_valid() instead of the devkit's -1).
#include "metrics.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fs::app {

cv::Mat fill_invalid_kitti(const cv::Mat& disp) {
  if (disp.type() != CV_32FC1) throw std::invalid_argument("fill_invalid_kitti: expected CV_32FC1");
  cv::Mat out = disp.clone();
  const int w = out.cols, h = out.rows;
  // Validity is tracked in a mask: a pixel filled in this row pass is "valid" for the column pass,
  // exactly as the devkit's in-place writes make it.
  cv::Mat valid(h, w, CV_8U);
  for (int y = 0; y < h; ++y) {
    const float* d = out.ptr<float>(y);
    unsigned char* m = valid.ptr<unsigned char>(y);
    for (int x = 0; x < w; ++x) m[x] = est_valid(d[x]) ? 1 : 0;
  }

  for (int y = 0; y < h; ++y) {
    float* d = out.ptr<float>(y);
    unsigned char* m = valid.ptr<unsigned char>(y);
    // Interior runs: min of the two valid neighbours (background).
    int count = 0;
    for (int x = 0; x < w; ++x) {
      if (m[x]) {
        if (count >= 1) {
          const int x1 = x - count, x2 = x - 1;
          if (x1 > 0 && x2 < w - 1) {
            const float fill = std::min(d[x1 - 1], d[x2 + 1]);
            for (int u = x1; u <= x2; ++u) {
              d[u] = fill;
              m[u] = 1;
            }
          }
        }
        count = 0;
      } else {
        ++count;
      }
    }
    // Extrapolate to the left and to the right with the nearest valid value.
    for (int x = 0; x < w; ++x) {
      if (m[x]) {
        for (int u = 0; u < x; ++u) {
          d[u] = d[x];
          m[u] = 1;
        }
        break;
      }
    }
    for (int x = w - 1; x >= 0; --x) {
      if (m[x]) {
        for (int u = x + 1; u < w; ++u) {
          d[u] = d[x];
          m[u] = 1;
        }
        break;
      }
    }
  }

  // Columns: extrapolate to the top and to the bottom (only rows that were entirely invalid).
  for (int x = 0; x < w; ++x) {
    for (int y = 0; y < h; ++y) {
      if (valid.at<unsigned char>(y, x)) {
        for (int v = 0; v < y; ++v) {
          out.at<float>(v, x) = out.at<float>(y, x);
          valid.at<unsigned char>(v, x) = 1;
        }
        break;
      }
    }
    for (int y = h - 1; y >= 0; --y) {
      if (valid.at<unsigned char>(y, x)) {
        for (int v = y + 1; v < h; ++v) {
          out.at<float>(v, x) = out.at<float>(y, x);
          valid.at<unsigned char>(v, x) = 1;
        }
        break;
      }
    }
  }
  return out;
}

DispMetrics evaluate_disparity(const cv::Mat& est, const cv::Mat& gt, const cv::Mat& area) {
  if (est.type() != CV_32FC1 || gt.type() != CV_32FC1)
    throw std::invalid_argument("evaluate_disparity: expected CV_32FC1 estimate and ground truth");
  return evaluate_filled(est, fill_invalid_kitti(est), gt, area);
}

DispMetrics evaluate_filled(const cv::Mat& est, const cv::Mat& filled, const cv::Mat& gt, const cv::Mat& area) {
  if (est.type() != CV_32FC1 || filled.type() != CV_32FC1 || gt.type() != CV_32FC1)
    throw std::invalid_argument("evaluate_filled: expected CV_32FC1 estimate, filled map and ground truth");
  if (est.size() != gt.size() || filled.size() != gt.size())
    throw std::invalid_argument("evaluate_filled: estimate, filled map and ground truth sizes differ");
  if (!area.empty() && (area.type() != CV_8UC1 || area.size() != gt.size()))
    throw std::invalid_argument("evaluate_filled: the evaluation area must be CV_8UC1 of the ground truth's size");

  // KITTI thresholds (evaluate_stereo.cpp: ABS_THRESH = 3, REL_THRESH = 0.05).
  constexpr double kAbsThresh = 3.0, kRelThresh = 0.05, kBad2 = 2.0;
  std::int64_t n = 0, n_dense = 0, n_bad2 = 0, n_bad3 = 0, n_d1 = 0;
  double sum_err = 0.0;
  for (int y = 0; y < gt.rows; ++y) {
    const float* g = gt.ptr<float>(y);
    const float* e0 = est.ptr<float>(y);
    const float* e = filled.ptr<float>(y);
    const unsigned char* a = area.empty() ? nullptr : area.ptr<unsigned char>(y);
    for (int x = 0; x < gt.cols; ++x) {
      if (!gt_valid(g[x]) || (a != nullptr && a[x] == 0)) continue;
      ++n;
      if (est_valid(e0[x])) ++n_dense;
      const double d_est = est_valid(e[x]) ? double(e[x]) : 0.0;  // whole map invalid: score against 0
      const double err = std::fabs(double(g[x]) - d_est);
      sum_err += err;
      if (err > kBad2) ++n_bad2;
      if (err > kAbsThresh) ++n_bad3;
      if (err > kAbsThresh && err / std::fabs(double(g[x])) > kRelThresh) ++n_d1;
    }
  }
  DispMetrics m;
  m.gt_pixels = n;
  if (n == 0) return m;
  const double dn = double(n);
  m.avg_err = sum_err / dn;
  m.bad2 = 100.0 * double(n_bad2) / dn;
  m.bad3 = 100.0 * double(n_bad3) / dn;
  m.d1 = 100.0 * double(n_d1) / dn;
  m.density = 100.0 * double(n_dense) / dn;
  return m;
}

}  // namespace fs::app
