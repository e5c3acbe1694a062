// KITTI-devkit hole filling and error metrics on hand-built maps with known answers.
#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "metrics.hpp"

namespace {

using fs::app::DispMetrics;
using fs::app::evaluate_disparity;
using fs::app::fill_invalid_kitti;

constexpr float kInv = -1.0f;
const float kNaN = std::numeric_limits<float>::quiet_NaN();

cv::Mat row_mat(const std::vector<float>& v) { return cv::Mat(v, true).reshape(1, 1); }

std::vector<float> to_vec(const cv::Mat& m) {
  std::vector<float> v;
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) v.push_back(m.at<float>(y, x));
  return v;
}

TEST(FillInvalidKitti, InteriorRunTakesSmallerNeighbour) {
  EXPECT_EQ(to_vec(fill_invalid_kitti(row_mat({5, kInv, kInv, 3, 7}))), (std::vector<float>{5, 3, 3, 3, 7}));
  EXPECT_EQ(to_vec(fill_invalid_kitti(row_mat({2, kNaN, 9}))), (std::vector<float>{2, 2, 9}));
}

TEST(FillInvalidKitti, BorderRunsTakeNearestValid) {
  EXPECT_EQ(to_vec(fill_invalid_kitti(row_mat({kInv, kInv, 4, kInv, 6, kInv}))),
            (std::vector<float>{4, 4, 4, 4, 6, 6}));
}

TEST(FillInvalidKitti, ZeroIsNoEstimateAsInTheKittiPng) {
  // 0 px cannot be written to a KITTI disparity PNG (0 = invalid), so it is filled like a hole.
  EXPECT_EQ(to_vec(fill_invalid_kitti(row_mat({0, kInv, 8}))), (std::vector<float>{8, 8, 8}));
  EXPECT_EQ(to_vec(fill_invalid_kitti(row_mat({6, 0, 8}))), (std::vector<float>{6, 6, 8}));
}

TEST(FillInvalidKitti, EmptyRowsAtTopAndBottomComeFromTheColumn) {
  // rows 0 and 3 empty -> extrapolated vertically; row 1 partially valid -> horizontal fill first.
  cv::Mat d = (cv::Mat_<float>(4, 3) << kInv, kInv, kInv,  //
               kInv, 5, kInv,                                //
               1, 2, 3,                                      //
               kInv, kInv, kInv);
  EXPECT_EQ(to_vec(fill_invalid_kitti(d)), (std::vector<float>{5, 5, 5, 5, 5, 5, 1, 2, 3, 1, 2, 3}));
}

TEST(FillInvalidKitti, EmptyRowBetweenValidRowsStaysInvalidLikeTheDevkit) {
  cv::Mat d = (cv::Mat_<float>(3, 2) << 1, 2, kInv, kInv, 5, 6);
  const cv::Mat f = fill_invalid_kitti(d);
  EXPECT_LT(f.at<float>(1, 0), 0.0f);
  EXPECT_LT(f.at<float>(1, 1), 0.0f);
}

TEST(EvaluateDisparity, KnownAnswer) {
  // GT: 0 = unknown. 4 GT-valid pixels.
  const cv::Mat gt = row_mat({10, 10, 0, 100, 40});
  // est: px0 exact, px1 invalid -> filled with min(10, 50) = 10 (exact), px2 no GT,
  //      px3 err 4 (> 3 px but 4 % of 100: bad3 yes, D1 no), px4 err 2.5 (bad2 only).
  const cv::Mat est = row_mat({10, kInv, 50, 96, 42.5f});
  const DispMetrics m = evaluate_disparity(est, gt);
  EXPECT_EQ(m.gt_pixels, 4);
  EXPECT_DOUBLE_EQ(m.avg_err, (0.0 + 0.0 + 4.0 + 2.5) / 4.0);
  EXPECT_DOUBLE_EQ(m.bad2, 50.0);
  EXPECT_DOUBLE_EQ(m.bad3, 25.0);
  EXPECT_DOUBLE_EQ(m.d1, 0.0);
  EXPECT_DOUBLE_EQ(m.density, 75.0);
}

TEST(EvaluateDisparity, D1NeedsBothAbsoluteAndRelative) {
  const cv::Mat gt = row_mat({20, 20, 200});
  const cv::Mat est = row_mat({24, 23, 190});  // err 4 (20 %), 3 (not > 3), 10 (5 %, not > 5 %)
  const DispMetrics m = evaluate_disparity(est, gt);
  EXPECT_NEAR(m.d1, 100.0 / 3.0, 1e-9);
  EXPECT_NEAR(m.bad3, 200.0 / 3.0, 1e-9);
  EXPECT_DOUBLE_EQ(m.density, 100.0);
}

TEST(EvaluateDisparity, LeftBandOfInvalidEstimatesIsFilledFromTheRight) {
  // An SGBM-like invalid left band: filled by the nearest valid value of the row.
  const cv::Mat gt = row_mat({7, 7, 7, 7});
  const cv::Mat est = row_mat({kInv, kInv, 7, 7});
  const DispMetrics m = evaluate_disparity(est, gt);
  EXPECT_DOUBLE_EQ(m.avg_err, 0.0);
  EXPECT_DOUBLE_EQ(m.density, 50.0);
}

TEST(EvaluateDisparity, AllInvalidEstimateScoresAgainstZero) {
  const DispMetrics m = evaluate_disparity(row_mat({kInv, kInv}), row_mat({4, 1}));
  EXPECT_DOUBLE_EQ(m.avg_err, 2.5);
  EXPECT_DOUBLE_EQ(m.density, 0.0);
  EXPECT_DOUBLE_EQ(m.bad3, 50.0);
  EXPECT_DOUBLE_EQ(m.d1, 50.0);
}

TEST(EvaluateDisparity, NoGroundTruthGivesZeros) {
  const DispMetrics m = evaluate_disparity(row_mat({1, 2}), row_mat({0, kNaN}));
  EXPECT_EQ(m.gt_pixels, 0);
  EXPECT_DOUBLE_EQ(m.avg_err, 0.0);
}

TEST(EvaluateDisparity, AreaScoresOnlyItsPixelsButFillsFromTheWholeMap) {
  // The known-answer row with px3 (err 4) outside the area: 3 scored pixels. px1 is still filled
  // from px0 and px2 although px2 has no GT (the fill sees the whole estimate).
  const cv::Mat gt = row_mat({10, 10, 0, 100, 40});
  const cv::Mat est = row_mat({10, kInv, 50, 96, 42.5f});
  cv::Mat area(1, 5, CV_8UC1, cv::Scalar(255));
  area.at<unsigned char>(0, 3) = 0;
  const DispMetrics m = evaluate_disparity(est, gt, area);
  EXPECT_EQ(m.gt_pixels, 3);
  EXPECT_DOUBLE_EQ(m.avg_err, 2.5 / 3.0);
  EXPECT_NEAR(m.bad2, 100.0 / 3.0, 1e-9);
  EXPECT_DOUBLE_EQ(m.bad3, 0.0);
  EXPECT_NEAR(m.density, 200.0 / 3.0, 1e-9);
  // An all-255 area scores exactly like no area.
  const DispMetrics all = evaluate_disparity(est, gt, cv::Mat(1, 5, CV_8UC1, cv::Scalar(255)));
  const DispMetrics none = evaluate_disparity(est, gt);
  EXPECT_EQ(all.gt_pixels, none.gt_pixels);
  EXPECT_DOUBLE_EQ(all.avg_err, none.avg_err);
}

TEST(EvaluateDisparity, RejectsMismatchedInputs) {
  EXPECT_THROW(evaluate_disparity(row_mat({1, 2}), row_mat({1, 2, 3})), std::invalid_argument);
  EXPECT_THROW(evaluate_disparity(cv::Mat(1, 2, CV_16S), row_mat({1, 2})), std::invalid_argument);
  EXPECT_THROW(evaluate_disparity(row_mat({1, 2}), row_mat({1, 2}), cv::Mat(1, 3, CV_8UC1, cv::Scalar(255))),
               std::invalid_argument);
  EXPECT_THROW(evaluate_disparity(row_mat({1, 2}), row_mat({1, 2}), cv::Mat(1, 2, CV_16UC1, cv::Scalar(1))),
               std::invalid_argument);
}

}  // namespace
