// ObstacleMap (firmware/robot/mapping/): hits raise cells, rays that see through a cell lower it,
// cells outside the view or beyond a column's free range are left alone, window queries.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "fuzzystereo/robot/obstacle_map.hpp"
#include "fuzzystereo/robot/static_support.hpp"

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

// A cell remembers the nearest range it was hit from since it became occupied; obstacles() marks it
// unconfirmed when that is beyond the confirmation range. A cell cleared and hit again starts over.
TEST(ObstacleMap, CellsSeenOnlyFromAfarAreUnconfirmed) {
  ObstacleMap map;
  CameraScan far = scan_at({0, 0, 0}, 0.0);
  far.hits = {{4.01, 0.01}};
  map.integrate(far);
  EXPECT_NEAR(map.nearest_hit_m({4.01, 0.01}), 4.01, 1e-3);
  auto obs = map.obstacles({0, 0}, 5.0, 3.0);
  ASSERT_EQ(obs.size(), 1u);
  EXPECT_TRUE(obs[0].unconfirmed);
  EXPECT_FALSE(map.obstacles({0, 0}, 5.0, 0.0)[0].unconfirmed);  // 0 = off
  EXPECT_FALSE(map.obstacles({0, 0}, 5.0, 4.5)[0].unconfirmed);
  // the robot comes to 2 m and hits it again: confirmed
  CameraScan near = scan_at({2.0, 0, 0}, 0.0);
  near.hits = {{4.02, 0.02}};
  map.integrate(near);
  EXPECT_NEAR(map.nearest_hit_m({4.01, 0.01}), 2.02, 1e-3);
  EXPECT_FALSE(map.obstacles({0, 0}, 5.0, 3.0)[0].unconfirmed);
  // seen through from 2 m until it is free (log-odds floor -2), then hit from 4 m until it is
  // occupied again (three frames): unconfirmed again
  CameraScan clear = scan_at({2.0, 0, 0}, 4.0);
  for (int k = 0; k < 20; ++k) map.integrate(clear);
  EXPECT_TRUE(map.obstacles({0, 0}, 5.0, 3.0).empty());
  EXPECT_TRUE(std::isinf(map.nearest_hit_m({4.01, 0.01})));
  for (int k = 0; k < 3; ++k) map.integrate(far);
  obs = map.obstacles({0, 0}, 5.0, 3.0);
  ASSERT_EQ(obs.size(), 1u);
  EXPECT_TRUE(obs[0].unconfirmed);
}

// occupied_before: a static surface seen from t = 0 supports a track that starts at 2 s; a mover's
// surface cells, occupied only when it arrives (3 s), do not support its track (first measured at
// 2.5 s, 1 m away); a cell that was cleared and hit again counts from the new hit.
TEST(ObstacleMap, OccupiedBeforeTellsOldSurfacesFromNewOnes) {
  ObstacleMap map;
  const std::int64_t s = 1'000'000'000;
  CameraScan wall = scan_at({0, 0, 0}, 0.0);
  wall.hits = {{2.0, 0.0}, {2.0, 0.07}, {2.0, 0.14}};  // three cells
  for (int k = 0; k <= 10; ++k) {  // 0 .. 1 s
    wall.t_ns = k * s / 10;
    map.integrate(wall);
  }
  EXPECT_EQ(map.occupied_before({2.1, 0.07}, 0.2, 2 * s - s), 3);  // occupied at t = 0 <= 1 s
  EXPECT_EQ(map.occupied_before({2.1, 0.07}, 0.2, -1), 0);        // not before the first scan
  EXPECT_EQ(map.occupied_before({2.1, 0.07}, 0.03, s), 0);        // radius: no hit point within 3 cm
  // A mover's surface at (3, 1), first hit at 3 s.
  CameraScan mover = scan_at({0, 0, 0}, 0.0);
  mover.hits = {{3.0, 1.0}, {3.0, 1.07}};
  mover.t_ns = 3 * s;
  map.integrate(mover);
  EXPECT_EQ(map.occupied_before({3.1, 1.0}, 0.2, 3 * s), 2);
  EXPECT_EQ(map.occupied_before({3.1, 1.0}, 0.2, static_cast<std::int64_t>(2.5 * s) - s), 0);
  // Clear the wall cells (free to 4 m; log-odds 3.5 -> below 0.4 after 8 frames), hit them again at
  // 10 s: they count from 10 s.
  CameraScan free4 = scan_at({0, 0, 0}, 4.0);
  for (int k = 0; k < 8; ++k) {
    free4.t_ns = 4 * s + k * s / 10;
    map.integrate(free4);
  }
  EXPECT_EQ(map.occupied_before({2.1, 0.07}, 0.2, 9 * s), 0);
  wall.t_ns = 10 * s;
  map.integrate(wall);
  EXPECT_EQ(map.occupied_before({2.1, 0.07}, 0.2, 9 * s), 0);
  EXPECT_EQ(map.occupied_before({2.1, 0.07}, 0.2, 10 * s), 3);
}

// has_static_support: a wall seen from the first frame of the run, its track born in that frame
// (the start of a run: map cells and track appear together). The lag test (cells occupied 1 s
// before the track's first measurement) never holds for it; the dwell test (cells occupied 2 s
// before its last measurement) holds once the wall has been seen for 2 s. A mover that keeps
// moving has fresh cells at its last position and passes neither.
TEST(StaticSupport, DwellSupportsTracksBornWithTheirCells) {
  ObstacleMap map;
  const std::int64_t s = 1'000'000'000;
  CameraScan wall = scan_at({0, 0, 0}, 0.0);
  wall.hits = {{2.0, 0.0}, {2.0, 0.07}, {2.0, 0.14}};
  Track tr;
  tr.radius_m = 0.1;
  tr.first_meas_ns = 0;
  tr.first_meas_p = {2.0, 0.07};
  tr.last_meas_p = {2.0, 0.07};
  const StaticSupportParams lag_only{2, 1.0, 0.0}, dwell{2, 1.0, 2.0};
  for (int k = 0; k <= 30; ++k) {  // 0 .. 3 s at 10 Hz
    wall.t_ns = k * s / 10;
    map.integrate(wall);
    tr.last_meas_ns = wall.t_ns;
    EXPECT_FALSE(has_static_support(map, tr, lag_only)) << k;
    EXPECT_EQ(has_static_support(map, tr, dwell), k >= 20) << k;  // seen for 2 s
  }
  EXPECT_EQ(static_support_cells(map, tr, 1.0), 0);
  EXPECT_FALSE(has_static_support(map, tr, {0, 1.0, 2.0}));  // cells = 0: the test is off
  // A mover at 0.1 m per frame (1 m/s) along y = 2: at each frame its cells are new.
  Track mv;
  mv.radius_m = 0.1;
  mv.first_meas_ns = 31 * s / 10;
  for (int k = 0; k < 30; ++k) {
    CameraScan sc = scan_at({0, 0, 0}, 0.0);
    const double y = 2.0 - 0.1 * k;
    sc.hits = {{3.0, y}, {3.0, y + 0.05}};
    sc.t_ns = (31 + k) * s / 10;
    map.integrate(sc);
    mv.last_meas_ns = sc.t_ns;
    mv.last_meas_p = {3.0, y + 0.025};
    EXPECT_FALSE(has_static_support(map, mv, dwell)) << k;
  }
}

// static_meas_age_s: a post seen for longer than the age is static (its points fall on old cells);
// at first sight it is not; a mover at 0.2 m/s reaches fresh cells every frame and never is; a
// mover that stops becomes static after the age (the map then holds it).
TEST(StaticSupport, MeasurementOnOldCellsIsStatic) {
  ObstacleMap map;
  const std::int64_t s = 1'000'000'000;
  CameraScan post = scan_at({0, 0, 0}, 0.0);
  post.hits = {{2.0, 0.0}, {2.01, 0.05}, {2.0, 0.1}};
  for (int k = 0; k <= 20; ++k) {  // 0 .. 2 s at 10 Hz, the points jitter by 1 cm
    post.t_ns = k * s / 10;
    std::vector<Vec2> h = post.hits;
    for (Vec2& p : h) p.x += (k % 2) * 0.01;
    EXPECT_EQ(measurement_is_static(map, h.data(), h.size(), post.t_ns - s, 0.6), k >= 10) << k;
    map.integrate(post);
  }
  EXPECT_FALSE(measurement_is_static(map, post.hits.data(), 0, post.t_ns, 0.6));  // no points
  // A mover crossing at 0.2 m/s (2 cm per frame) towards the camera, seen for 3 s: never static.
  for (int k = 0; k < 30; ++k) {
    CameraScan sc = scan_at({0, 0, 0}, 0.0);
    const double x = 3.5 - 0.02 * k;
    sc.hits = {{x, -1.0}, {x + 0.02, -0.95}, {x + 0.04, -0.9}};
    sc.t_ns = (21 + k) * s / 10;
    EXPECT_FALSE(measurement_is_static(map, sc.hits.data(), sc.hits.size(), sc.t_ns - s, 0.6)) << k;
    map.integrate(sc);
  }
  // It stops: static at the latest once its own cells are older than the age (sooner when the
  // cells of its trail just behind it, which this camera never sees through, are that old).
  CameraScan st = scan_at({0, 0, 0}, 0.0);
  st.hits = {{2.92, -1.0}, {2.94, -0.95}, {2.96, -0.9}};
  for (int k = 0; k <= 12; ++k) {
    st.t_ns = (51 + k) * s / 10;
    const bool is_static = measurement_is_static(map, st.hits.data(), st.hits.size(), st.t_ns - s, 0.6);
    if (k <= 3) {
      EXPECT_FALSE(is_static) << k;
    }
    if (k >= 10) {
      EXPECT_TRUE(is_static) << k;
    }
    map.integrate(st);
  }
}

// A flat face sliding along itself (a cylinder crossing the view shows its front that way) keeps
// hitting the same cells except at its leading edge: the silhouette-end test keeps it from being
// static, although most of its points lie on old cells. min_frames: cells a passing surface hit in
// only a frame or two do not count.
TEST(StaticSupport, SlidingFaceIsNotStaticAndBrieflyHitCellsDoNotCount) {
  ObstacleMap map;
  const std::int64_t s = 1'000'000'000;
  auto face = [](double y0) {
    std::vector<Vec2> h;
    for (int k = 0; k < 10; ++k) h.push_back({2.0, y0 + 0.03 * k});
    return h;
  };
  // The face slides 1.5 cm per frame (0.15 m/s at 10 Hz) for 3 s.
  bool any_static = false;
  for (int k = 0; k < 30; ++k) {
    CameraScan sc = scan_at({0, 0, 0}, 0.0);
    sc.hits = face(-0.5 + 0.015 * k);
    sc.t_ns = k * s / 10;
    if (k >= 10) {
      // half of its points lie on cells older than 1 s (the whole-surface share 0.5 passes) ...
      std::size_t old = 0;
      for (const Vec2& h : sc.hits) old += map.occupied_before(h, map.params().cell_m, sc.t_ns - s) > 0;
      EXPECT_GE(old, 5u) << k;
      // ... but its leading edge does not
      any_static = any_static || measurement_is_static(map, sc.hits.data(), sc.hits.size(), sc.t_ns - s, 0.5);
    }
    map.integrate(sc);
  }
  EXPECT_FALSE(any_static);
  // A face standing still for 2 s is static.
  CameraScan st = scan_at({0, 0, 0}, 0.0);
  st.hits = face(1.0);
  for (int k = 0; k <= 20; ++k) {
    st.t_ns = (40 + k) * s / 10;
    const bool is_static = measurement_is_static(map, st.hits.data(), st.hits.size(), st.t_ns - s, 0.6, 4);
    EXPECT_EQ(is_static, k >= 10) << k;
    map.integrate(st);
  }
  // Cells hit in one frame only, 1.5 s ago and never seen through since: old, but not stable.
  CameraScan once = scan_at({0, 0, 0}, 0.0);
  once.hits = face(-1.5);
  once.t_ns = 70 * s / 10;
  map.integrate(once);
  const std::int64_t now = 85 * s / 10;
  EXPECT_TRUE(measurement_is_static(map, once.hits.data(), once.hits.size(), now - s, 0.6, 0));
  EXPECT_FALSE(measurement_is_static(map, once.hits.data(), once.hits.size(), now - s, 0.6, 2));
}

// static_track_born_s: a track born with the map (no history to test) is supported while the cells
// at its birthplace stay occupied and it stays near it; a mover that leaves its birthplace in view
// is seen through there and loses the support; a track born later, or one that travelled, gets none.
TEST(StaticSupport, BornWithTheMapKeepsStaticObstaclesNotMoversThatLeave) {
  ObstacleMap map;
  const std::int64_t s = 1'000'000'000;
  StaticSupportParams born{2, 1.0, 0.0, 2.0, 1.0};
  StaticSupportParams off = born;
  off.born_s = 0.0;
  Track post;  // on a wall at x = 2, seen from the first frame on
  post.radius_m = 0.1;
  post.first_meas_ns = 0;
  post.first_meas_p = post.last_meas_p = {2.0, 0.07};
  Track mover = post;  // at x = 3, y = 0.5 at the start, walks 0.6 m along +y at 0.5 m/s, then stands
  mover.first_meas_p = mover.last_meas_p = {3.0, 0.5};
  for (int k = 0; k <= 30; ++k) {  // 0 .. 3 s at 10 Hz
    CameraScan sc = scan_at({0, 0, 0}, 0.0);
    sc.t_ns = k * s / 10;
    sc.hits = {{2.0, 0.0}, {2.0, 0.07}, {2.0, 0.14}};
    const double my = 0.5 + 0.05 * std::min(k, 12);
    sc.hits.push_back({3.0, my});
    sc.hits.push_back({3.0, my + 0.05});
    // Each column sees free space up to the first surface on it: the wall (x = 2), the mover
    // (x = 3) or nothing up to 4 m (so the mover's birthplace is seen through once it has left).
    for (int c = 0; c < 64; ++c) {
      const double t = std::tan(std::atan2(31.5 - c, 40.0));
      const bool wall = 2.0 * t > -0.1 && 2.0 * t < 0.25, on_mover = 3.0 * t > my - 0.1 && 3.0 * t < my + 0.15;
      sc.free_range_m[std::size_t(c)] = wall ? 1.95 : on_mover ? 2.95 : 4.0;
    }
    map.integrate(sc);
    post.last_meas_ns = mover.last_meas_ns = sc.t_ns;
    mover.last_meas_p = {3.0, my + 0.025};
    EXPECT_TRUE(has_static_support(map, post, born)) << k;
    EXPECT_FALSE(has_static_support(map, post, off)) << k;  // born with its cells: the lag test cannot hold
    if (k >= 12) {  // its birthplace seen through, its new cells occupied, 0.6 m travelled
      EXPECT_FALSE(has_static_support(map, mover, born)) << k;
      if (k >= 20) {
        EXPECT_GE(map.occupied_before(mover.last_meas_p, 0.15, sc.t_ns), 2) << k;
      }
    }
  }
  EXPECT_EQ(map.first_scan_ns(), 0);
  // The same post, first measured after the born window (3 s > 2 s), needs the lag test instead.
  Track late = post;
  late.first_meas_ns = 3 * s;
  EXPECT_FALSE(has_static_support(map, late, StaticSupportParams{2, 5.0, 0.0, 2.0, 1.0}));
  // A track whose measurements are 1.2 m apart is not a static obstacle's jitter.
  Track far = post;
  far.first_meas_p = {2.0, -1.13};
  map.integrate([&] {
    CameraScan sc = scan_at({0, 0, 0}, 0.0);
    sc.t_ns = 31 * s / 10;
    sc.hits = {{2.0, -1.13}, {2.0, -1.08}};
    return sc;
  }());
  EXPECT_FALSE(has_static_support(map, far, born));
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


// What the camera saw and when ([planner] unseen_check_s): cells in the view up to the column's free
// range, also nearer than min_range_m, and surface cells; not behind the robot, not beyond the free
// range, not outside the view; a later scan that sees the cell again moves its time on.
TEST(ObstacleMap, RemembersWhenTheCameraLastSawTheGround) {
  constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::min();
  ObstacleMapParams mp;
  mp.remember_seen = true;
  ObstacleMap map(mp);
  EXPECT_EQ(map.last_seen_ns({1.0, 0.0}), kNever);  // before the first scan
  CameraScan s = scan_at({0, 0, 0}, 2.0);  // +-38.7 deg view, free to 2 m
  s.hits = {{3.0, 0.0}};
  s.t_ns = 100;
  map.integrate(s);
  EXPECT_EQ(map.last_seen_ns({1.0, 0.0}), 100);
  EXPECT_EQ(map.last_seen_ns({0.2, 0.0}), 100);   // nearer than min_range_m (0.3 m)
  EXPECT_EQ(map.last_seen_ns({3.0, 0.0}), 100);   // the surface point
  EXPECT_EQ(map.last_seen_ns({2.5, 0.0}), kNever);  // between the free range and the surface
  EXPECT_EQ(map.last_seen_ns({-1.0, 0.0}), kNever);  // behind
  EXPECT_EQ(map.last_seen_ns({1.0, 1.5}), kNever);   // outside the view (56 deg)
  EXPECT_EQ(map.last_seen_ns({1e3, 0.0}), kNever);   // off the grid
  s = scan_at({0, 0, M_PI / 2}, 2.0);  // turned left
  s.t_ns = 200;
  map.integrate(s);
  EXPECT_EQ(map.last_seen_ns({0.0, 1.0}), 200);
  EXPECT_EQ(map.last_seen_ns({1.0, 0.0}), 100);  // not in this view: the older time stays
}

}  // namespace
}  // namespace fs::robot
