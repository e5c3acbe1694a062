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

namespace {

// The next rung, --oracle-detections: the simulator's truth as the detector's output.
TEST(OracleDetections, OneObstaclePerVisibleSceneObstacleNearestFirstWithTheTrueRoad) {
  fs::sim::RenderResult rr;
  const int w = 40, h = 20;
  rr.disparity = fs::Image<float>(w, h, 0.0f);
  rr.obstacle_ids = fs::ImageI32(w, h, -1);
  rr.road_mask = fs::ImageU8(w, h, 0);
  for (int y = 15; y < h; ++y)
    for (int x = 0; x < w; ++x) rr.road_mask.at(x, y) = 255, rr.disparity.at(x, y) = 3.0f;
  // obstacle 0: far (4 px) at x 2..11, y 2..11; obstacle 1: near (10 px, one pixel 10.5) at x 20..29, y 5..14;
  // obstacle 2: 4 pixels only; obstacle 3: nearer than the search range (no valid pixel)
  for (int y = 2; y < 12; ++y)
    for (int x = 2; x < 12; ++x) rr.obstacle_ids.at(x, y) = 0, rr.disparity.at(x, y) = 4.0f;
  for (int y = 5; y < 15; ++y)
    for (int x = 20; x < 30; ++x) rr.obstacle_ids.at(x, y) = 1, rr.disparity.at(x, y) = 10.0f;
  rr.disparity.at(20, 5) = 10.5f;
  for (int x = 33; x < 37; ++x) rr.obstacle_ids.at(x, 3) = 2, rr.disparity.at(x, 3) = 6.0f;
  for (int x = 33; x < 39; ++x)
    for (int y = 6; y < 14; ++y) rr.obstacle_ids.at(x, y) = 3, rr.disparity.at(x, y) = 70.0f;
  rr.obstacles.resize(4);
  for (int i = 0; i < 4; ++i) rr.obstacles[std::size_t(i)].id = i;
  const fs::ImageI16 disp = fs::app::oracle_disparity_q4(rr.disparity, 64);
  fs::StereoCalib calib;
  calib.focal_px = 100.0, calib.baseline_m = 0.1, calib.cx = 20.0, calib.cy = 10.0;
  const fs::DetectParams p;
  const fs::DetectResult r = fs::app::oracle_detections_of(rr, disp, calib, p, 5);
  ASSERT_EQ(r.obstacles.size(), 2u);
  const fs::Obstacle& n = r.obstacles[0];  // nearest first
  EXPECT_EQ(n.id, 0);
  EXPECT_EQ(std::vector<int>({n.x0, n.y0, n.x1, n.y1}), std::vector<int>({20, 5, 29, 14}));
  EXPECT_EQ(n.pixel_count, 100);
  EXPECT_EQ(n.disparity_q4, 10 * fs::kDispScale);  // the median, not the outlier
  EXPECT_DOUBLE_EQ(n.distance_m, 1.0);
  EXPECT_EQ(n.cls, fs::detect::classify_distance(1.0, p));
  const fs::Obstacle& f = r.obstacles[1];
  EXPECT_EQ(std::vector<int>({f.x0, f.y0, f.x1, f.y1}), std::vector<int>({2, 2, 11, 11}));
  EXPECT_DOUBLE_EQ(f.distance_m, 2.5);
  EXPECT_EQ(r.obstacle_labels.at(25, 10), 1);  // id + 1
  EXPECT_EQ(r.obstacle_labels.at(5, 5), 2);
  EXPECT_EQ(r.obstacle_labels.at(34, 3), 0);   // too few pixels: no obstacle
  EXPECT_EQ(r.obstacle_labels.at(35, 8), 0);   // outside the search range
  EXPECT_EQ(r.road_mask.at(3, 16), 1);
  EXPECT_EQ(r.road_mask.at(3, 3), 0);
}

}  // namespace

namespace {

// The last rung, --oracle-world: footprints as planner circles that cover them, with true velocities.
TEST(OracleWorld, CirclesCoverEachFootprintAndCarryItsVelocity) {
  fs::sim::Footprint wall;  // 2 m x 0.2 m, turned 30 deg
  wall.id = 3, wall.x_m = 1.0, wall.y_m = -2.0, wall.yaw_rad = 0.5235987755982988, wall.half_length_m = 1.0,
  wall.half_width_m = 0.1;
  fs::sim::Footprint across = wall;  // half_width > half_length: the long axis is across the yaw
  across.id = 4, across.half_length_m = 0.05, across.half_width_m = 0.4, across.yaw_rad = 0.0;
  fs::sim::Footprint post;
  post.id = 7, post.circle = true, post.x_m = 3.0, post.y_m = 0.5, post.radius_m = 0.25;
  fs::sim::Footprint post_later = post;
  post_later.x_m += 0.08, post_later.y_m -= 0.04;  // 0.8, -0.4 m/s over 0.1 s
  const auto c = fs::app::oracle_world_circles({wall, across, post}, {wall, across, post_later}, 0.1);
  std::vector<fs::robot::CircleObstacle> p;
  for (const auto& o : c)
    if (o.r == post.radius_m) p.push_back(o);
  ASSERT_EQ(p.size(), 1u);
  EXPECT_NEAR(p[0].vel.x, 0.8, 1e-9);
  EXPECT_NEAR(p[0].vel.y, -0.4, 1e-9);
  // every point of each box lies in one of the circles, and the circles stay within 0.15 m of the box
  for (const auto* f : {&wall, &across}) {
    const double ca = std::cos(f->yaw_rad), sa = std::sin(f->yaw_rad);
    for (double u = -f->half_length_m; u <= f->half_length_m + 1e-9; u += f->half_length_m / 20)
      for (double v = -f->half_width_m; v <= f->half_width_m + 1e-9; v += f->half_width_m / 10) {
        const double x = f->x_m + u * ca - v * sa, y = f->y_m + u * sa + v * ca;
        bool in = false;
        for (const auto& o : c) in = in || std::hypot(x - o.c.x, y - o.c.y) <= o.r + 1e-9;
        EXPECT_TRUE(in) << f->id << " " << u << " " << v;
      }
  }
  std::size_t boxes = 0;
  for (const auto& o : c)
    if (o.r != post.radius_m) {
      ++boxes;
      EXPECT_LE(o.r, std::hypot(0.1, 0.1) + 1e-9);  // wall slices: half width 0.1, slices <= 0.2 long
      EXPECT_EQ(o.vel.x, 0.0);
    }
  EXPECT_EQ(boxes, 10u + 8u);  // 2 m / 0.2 m and 0.8 m / 0.1 m
}

}  // namespace
