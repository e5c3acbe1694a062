// Road slope prior (docs/detection.md "(a) Slope prior"): with the mounting known, the road line's slope is
// limited to a factor around B cos(pitch) / h, so two obstacles stacked in depth cannot pass for the road.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

StereoCalib mounted(double height_m, double pitch_rad = 0.0) {
  StereoCalib c;
  c.focal_px = 200, c.cx = 120, c.cy = 90, c.baseline_m = 0.1, c.height_m = height_m, c.pitch_rad = pitch_rad;
  return c;
}

TEST(DetectSlopePrior, RangeFollowsTheMounting) {
  DetectParams p;  // road_slope_min 0.02, road_slope_max 2
  double lo = 0, hi = 0;
  p.road_slope_prior_rel = 0.5;
  ASSERT_TRUE(detect::road_slope_range(p, mounted(0.5), &lo, &hi));  // a0 = 0.1 / 0.5 = 0.2
  EXPECT_NEAR(lo, 0.2 / 1.5, 1e-12);
  EXPECT_NEAR(hi, 0.3, 1e-12);
  ASSERT_TRUE(detect::road_slope_range(p, mounted(0.5, 0.5), &lo, &hi));  // cos(0.5) shortens it
  EXPECT_NEAR(hi, 0.3 * std::cos(0.5), 1e-12);
  ASSERT_TRUE(detect::road_slope_range(p, mounted(0.0), &lo, &hi));  // mounting unknown: the plain range
  EXPECT_EQ(lo, 0.02);
  EXPECT_EQ(hi, 2.0);
  p.road_slope_prior_rel = 0.0;  // off
  ASSERT_TRUE(detect::road_slope_range(p, mounted(0.5), &lo, &hi));
  EXPECT_EQ(lo, 0.02);
  EXPECT_EQ(hi, 2.0);
  p.road_slope_prior_rel = 0.1, p.road_slope_max = 0.1;  // [0.18, 0.22] and [0.02, 0.1] do not meet
  EXPECT_FALSE(detect::road_slope_range(p, mounted(0.5), &lo, &hi));
}

TEST(DetectSlopePrior, StackedObstaclesDoNotPassForTheRoad) {
  // 240x180: two walls over columns 0..199 (d = 7 px in rows 20..99, 9 px in rows 100..179) form a v-disparity
  // line of slope ~0.025 with 8x the support of the true road (d = 0.2 (v - 90), columns 200..239, rows 91..179).
  const int w = 240, h = 180;
  ImageI16 disp(w, h, kInvalidDisp);
  for (int y = 20; y < h; ++y)
    for (int x = 0; x < 200; ++x) disp.at(x, y) = std::int16_t(y < 100 ? 7 * 16 : 9 * 16);
  for (int y = 91; y < h; ++y)
    for (int x = 200; x < w; ++x) disp.at(x, y) = std::int16_t(std::lround(16 * 0.2 * (y - 90)));
  DetectParams p;
  p.road_slope_prior_rel = 0.0;
  const DetectResult off = Detector(p).detect(disp, ImageRgb8{}, mounted(0.5));
  ASSERT_TRUE(off.road.found);
  EXPECT_LT(off.road.a, 0.05);  // the walls were taken for the road
  p.road_slope_prior_rel = 0.5;
  const DetectResult on = Detector(p).detect(disp, ImageRgb8{}, mounted(0.5));
  ASSERT_TRUE(on.road.found);
  EXPECT_NEAR(on.road.a, 0.2, 0.01);
  EXPECT_NEAR(on.road.horizon_row, 91, 1);
}

}  // namespace
}  // namespace fs
