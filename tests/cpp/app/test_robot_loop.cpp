// The closed loop's simulator diagnostic `--oracle-disparity` (docs/robot.md "Session 45"): the rendered
// ground-truth disparity turned into what a perfect matcher with the same search range would output.
#include <gtest/gtest.h>

#include "robot_loop.hpp"

namespace {

TEST(OracleDisparity, ExactValuesInTheMatchersRangeAndInvalidOutsideIt) {
  fs::Image<float> d(7, 2, 0.0f);
  const float row0[7] = {0.0f, -1.0f, 0.49f, 10.03f, 95.99f, 96.0f, 120.0f};
  for (int x = 0; x < 7; ++x) d.at(x, 0) = row0[x];
  d.at(3, 1) = 1.0f / 32.0f;  // rounds to 1 in Q4 (0.5 rounds away from zero)
  const fs::ImageI16 q = fs::app::oracle_disparity_q4(d, 96);
  ASSERT_EQ(q.width, 7);
  ASSERT_EQ(q.height, 2);
  EXPECT_EQ(q.at(0, 0), fs::kInvalidDisp);  // no hit (sky)
  EXPECT_EQ(q.at(1, 0), fs::kInvalidDisp);
  EXPECT_EQ(q.at(2, 0), 8);                 // 0.49 px * 16 = 7.84
  EXPECT_EQ(q.at(3, 0), 160);               // 10.03 px * 16 = 160.48
  EXPECT_EQ(q.at(4, 0), 1536);              // 95.99 px * 16 = 1535.84
  EXPECT_EQ(q.at(5, 0), fs::kInvalidDisp);  // the matcher searches [0, 96): nearer than its range
  EXPECT_EQ(q.at(6, 0), fs::kInvalidDisp);
  EXPECT_EQ(q.at(3, 1), 1);
  EXPECT_EQ(q.at(0, 1), fs::kInvalidDisp);
}

}  // namespace
