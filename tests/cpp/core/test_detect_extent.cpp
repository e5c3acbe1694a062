// Box extent (docs/detection.md "(e) Box extent"): ground contact on a hand-made road line table and
// on the synthetic two-box scene, where the road band removes the boxes' lowest rows.
#include <gtest/gtest.h>

#include <climits>
#include <cmath>
#include <cstdint>
#include <vector>

#include "detect_scene.hpp"
#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

// Road line d = 0.2 * (v - 50) px, 120 rows; rows <= 50 have no line value.
std::vector<std::int32_t> line_table(int rows) {
  std::vector<std::int32_t> t(std::size_t(rows), INT32_MIN);
  for (int v = 51; v < rows; ++v) t[std::size_t(v)] = std::int32_t(std::lround(16 * 0.2 * (v - 50)));
  return t;
}

Obstacle box_at(int y1, int disparity_q4) {
  Obstacle o;
  o.x0 = 10, o.x1 = 30, o.y0 = 20, o.y1 = y1, o.disparity_q4 = disparity_q4;
  return o;
}

TEST(DetectExtent, GroundContactExtendsBottomToWhereTheLineReachesTheDisparity) {
  DetectParams p;  // road band 1 px + 0.02 * line; slack 0.5 px
  p.foot_extend = true;
  p.foot_slack_px = 0.0;
  // d = 10 px (160 Q4): the line reaches 160 at row 100, so the obstacle's lowest row is 99. Row 94: line 141 (round(140.8)), band
  // round(16 + 0.02 * 141) = 19 -> 141 >= 160 - 19: a box ending at row 93 touches the band.
  std::vector<Obstacle> obs{box_at(93, 160), box_at(92, 160), box_at(100, 160), box_at(105, 160), box_at(40, 160)};
  detect::extend_to_ground(obs, line_table(120), p);
  EXPECT_EQ(obs[0].y1, 99);   // extended to the foot row
  EXPECT_EQ(obs[1].y1, 92);   // row 93: line 138 < 141: one row of road beyond the band, not touching
  EXPECT_EQ(obs[2].y1, 100);  // at or below the foot already: unchanged
  EXPECT_EQ(obs[3].y1, 105);  // reaches below the foot: never shortened
  EXPECT_EQ(obs[4].y1, 40);   // row 41 is above the horizon (no line value)
  EXPECT_EQ(obs[0].y0, 20);
  EXPECT_EQ(obs[0].x0, 10);
  EXPECT_EQ(obs[0].x1, 30);
  // The slack admits the box ending one row higher (138 >= 141 - 8).
  p.foot_slack_px = 0.5;
  obs = {box_at(92, 160)};
  detect::extend_to_ground(obs, line_table(120), p);
  EXPECT_EQ(obs[0].y1, 99);
  // Foot below the image (the line reaches d = 15 px at row 125 > 119): row 117's line 214 >= 240 -
  // 20 - 8, so the box ending at 116 touches the band and ends at the last row.
  obs = {box_at(116, 240)};
  detect::extend_to_ground(obs, line_table(120), p);
  EXPECT_EQ(obs[0].y1, 119);
  // Off: unchanged.
  p.foot_extend = false;
  obs = {box_at(93, 160)};
  detect::extend_to_ground(obs, line_table(120), p);
  EXPECT_EQ(obs[0].y1, 93);
}

TEST(DetectExtent, SceneBoxesReachTheirTrueBottomRow) {
  // 240x180, f = 200, B = 0.1, h = 0.5: box A at 2 m spans rows 90..140, box B at 4 m rows 95..115.
  // The road band takes ~6 rows of A's foot and ~5 of B's; ground contact gives them back.
  const auto s = test::make_scene(240, 180, {{40, 90, 2.0, 0.5}, {150, 200, 4.0, 0.4}}, 5, 0.25, 0.03, 200.0);
  DetectParams p;
  for (bool on : {false, true}) {
    p.foot_extend = on;
    const DetectResult r = Detector(p).detect(s.disp, s.rgb, s.calib);
    ASSERT_EQ(r.obstacles.size(), 2u);
    for (int i = 0; i < 2; ++i) {
      const int err = r.obstacles[std::size_t(i)].y1 - s.boxes[std::size_t(i)][3];
      if (on) EXPECT_LE(std::abs(err), 1) << "box " << i;
      else EXPECT_LE(err, -3) << "box " << i;  // the band's rows are missing without it
    }
  }
}

}  // namespace
}  // namespace fs
