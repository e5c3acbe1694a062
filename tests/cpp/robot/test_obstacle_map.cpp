// ObstacleMap (firmware/robot/mapping/): hits raise cells, rays that see through a cell lower it,
// cells outside the view or beyond a column's free range are left alone, window queries.
#include <gtest/gtest.h>

#include <cmath>

#include "fuzzystereo/robot/obstacle_map.hpp"

namespace fs::robot {
namespace {

// A 64-column camera at the pose, f = 40 px (77 deg view), every column seeing free space to `free_m`.
CameraScan scan_at(Pose2D pose, double free_m) {
  CameraScan s;
  s.pose = pose;
  s.focal_px = 40.0;
  s.cx = 31.5;
  s.min_range_m = 0.3;
  s.free_range_m.assign(64, free_m);
  return s;
}

TEST(ObstacleMap, HitsBecomeOccupiedAtTheMeanOfTheirPoints) {
  ObstacleMap map;
  EXPECT_TRUE(map.obstacles({0, 0}, 10.0).empty());  // before the first scan
  CameraScan s = scan_at({0, 0, 0}, 0.0);
  s.hits = {{2.011, 0.512}, {2.019, 0.518}};  // both in one 5 cm cell
  map.integrate(s);
  // one frame: +0.85 once (not once per point) > 0.4
  auto obs = map.obstacles({0, 0}, 5.0);
  ASSERT_EQ(obs.size(), 1u);
  EXPECT_NEAR(obs[0].c.x, 2.015, 1e-3);
  EXPECT_NEAR(obs[0].c.y, 0.515, 1e-3);
  EXPECT_DOUBLE_EQ(obs[0].r, 0.025);
  EXPECT_EQ(map.occupied_count(), 1);
  // the radius query excludes it
  EXPECT_TRUE(map.obstacles({0, 0}, 1.5).empty());
  EXPECT_EQ(map.obstacles({2.0, 0.5}, 0.1).size(), 1u);
}

TEST(ObstacleMap, SeeingThroughACellClearsItOnlyAfterEnoughFrames) {
  ObstacleMap map;
  CameraScan s = scan_at({0, 0, 0}, 0.0);
  s.hits = {{2.0, 0.0}};
  map.integrate(s);
  map.integrate(s);  // log-odds 1.7
  ASSERT_EQ(map.occupied_count(), 1);
  // Now the columns see free space to 4 m: -0.4 per frame; 1.7 - 3 * 0.4 = 0.5 > 0.4, 4th frame 0.1.
  const CameraScan free4 = scan_at({0, 0, 0}, 4.0);
  for (int k = 0; k < 3; ++k) {
    map.integrate(free4);
    EXPECT_EQ(map.occupied_count(), 1) << "after " << k + 1 << " free frames";
  }
  map.integrate(free4);
  EXPECT_EQ(map.occupied_count(), 0);
}

TEST(ObstacleMap, CellsBeyondTheFreeRangeOrOutsideTheViewStay) {
  ObstacleMap map;
  CameraScan s = scan_at({0, 0, 0}, 0.0);
  s.hits = {{2.0, 0.0}, {0.0, 2.0}, {-2.0, 0.0}};  // ahead, left (outside the view), behind
  map.integrate(s);
  ASSERT_EQ(map.occupied_count(), 3);
  // Free only up to 1.5 m: the cell at 2 m is beyond it; the others are not in the view.
  for (int k = 0; k < 10; ++k) map.integrate(scan_at({0, 0, 0}, 1.5));
  EXPECT_EQ(map.occupied_count(), 3);
  // Columns without knowledge (free range 0) clear nothing either.
  for (int k = 0; k < 10; ++k) map.integrate(scan_at({0, 0, 0}, 0.0));
  EXPECT_EQ(map.occupied_count(), 3);
  // Turning left by 90 degrees puts (0, 2) in the view: only it is cleared.
  for (int k = 0; k < 10; ++k) map.integrate(scan_at({0, 0, M_PI / 2}, 4.0));
  EXPECT_EQ(map.occupied_count(), 2);
  EXPECT_TRUE(map.obstacles({0.0, 2.0}, 0.2).empty());
  EXPECT_EQ(map.obstacles({2.0, 0.0}, 0.2).size(), 1u);
  EXPECT_EQ(map.obstacles({-2.0, 0.0}, 0.2).size(), 1u);
}

TEST(ObstacleMap, AHitThisFrameIsNotClearedByTheSameFrame) {
  ObstacleMap map;
  CameraScan s = scan_at({0, 0, 0}, 4.0);  // free range passes the hit (a surface seen through)
  s.hits = {{2.0, 0.0}};
  for (int k = 0; k < 5; ++k) map.integrate(s);
  EXPECT_EQ(map.occupied_count(), 1);
}

TEST(ObstacleMap, ClampBoundsHowLongACellTakesToChangeItsMind) {
  ObstacleMapParams p;
  ObstacleMap map(p);
  CameraScan s = scan_at({0, 0, 0}, 0.0);
  s.hits = {{2.0, 0.0}};
  for (int k = 0; k < 100; ++k) map.integrate(s);  // saturates at l_max = 3.5
  const CameraScan free4 = scan_at({0, 0, 0}, 4.0);
  // (3.5 - 0.4) / 0.4 = 7.75: cleared on the 8th free frame, not later however long it was seen.
  int frames = 0;
  while (map.occupied_count() > 0 && frames < 100) {
    map.integrate(free4);
    ++frames;
  }
  EXPECT_EQ(frames, 8);
}

TEST(ObstacleMap, HitsOutsideTheGridAreIgnored) {
  ObstacleMapParams p;
  p.extent_m = 4.0;  // +-2 m around the first pose
  ObstacleMap map(p);
  CameraScan s = scan_at({0, 0, 0}, 0.0);
  s.hits = {{5.0, 0.0}, {-3.0, 0.0}, {1.0, 1.0}};
  map.integrate(s);
  EXPECT_EQ(map.occupied_count(), 1);
  EXPECT_EQ(map.obstacles({0, 0}, 100.0).size(), 1u);  // query window clamped to the grid
}

}  // namespace
}  // namespace fs::robot
