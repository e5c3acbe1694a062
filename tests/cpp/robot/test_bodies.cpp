// Hidden sides of mapped obstacles (firmware/robot/mapping/bodies.cpp): circle fits to groups of
// occupied map cells, and the map's seen-free share that rejects fits to concave groups.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "fuzzystereo/robot/bodies.hpp"
#include "fuzzystereo/robot/obstacle_map.hpp"

namespace fs::robot {
namespace {

// Points on the arc [a0, a1] (deg) of the circle (c, r), n of them, with Gaussian noise sigma.
std::vector<Vec2> arc_points(Vec2 c, double r, double a0, double a1, int n, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  std::vector<Vec2> p;
  for (int i = 0; i < n; ++i) {
    const double a = (a0 + (a1 - a0) * i / (n - 1)) * M_PI / 180.0;
    p.push_back({c.x + r * std::cos(a) + noise(rng), c.y + r * std::sin(a) + noise(rng)});
  }
  return p;
}

std::vector<CircleObstacle> as_cells(const std::vector<Vec2>& pts) {
  std::vector<CircleObstacle> cells;
  for (const Vec2& p : pts) cells.push_back({p, 0.025, {}});
  return cells;
}

TEST(FitCircle, ExactArcGivesTheCircle) {
  // A half circle far from the origin (the centring keeps it well conditioned).
  const CircleFit f = fit_circle(arc_points({102.3, -57.1}, 0.4, -90, 90, 30, 0.0, 1));
  ASSERT_TRUE(f.ok);
  EXPECT_NEAR(f.c.x, 102.3, 1e-6);
  EXPECT_NEAR(f.c.y, -57.1, 1e-6);
  EXPECT_NEAR(f.r, 0.4, 1e-6);
  EXPECT_NEAR(f.rms, 0.0, 1e-6);
  EXPECT_NEAR(f.arc_deg, 180.0, 1e-6);
}

TEST(FitCircle, NoisyShortArcIsNotBiasedSmall) {
  // 70 deg of a 0.3 m circle with 1 cm noise, over 200 draws: the geometric refinement keeps the
  // radius unbiased within 1 cm on average (the algebraic fit alone shrinks short arcs).
  double mean_err = 0.0;
  for (unsigned s = 0; s < 200; ++s) {
    const CircleFit f = fit_circle(arc_points({1.0, 2.0}, 0.3, 10, 80, 25, 0.01, s));
    ASSERT_TRUE(f.ok) << s;
    mean_err += (f.r - 0.3) / 200.0;
  }
  EXPECT_LT(std::fabs(mean_err), 0.01);
}

TEST(FitCircle, DegenerateInputsAreNotOk) {
  EXPECT_FALSE(fit_circle({}).ok);
  EXPECT_FALSE(fit_circle({{0, 0}, {1, 1}}).ok);
  // collinear: no finite circle (or one so large that every caller rejects it)
  const CircleFit line = fit_circle({{0, 0}, {1, 0}, {2, 0}, {3, 0}});
  EXPECT_TRUE(!line.ok || line.r > 1e3);
}

TEST(FitBodies, RoundGroupsBecomeCirclesStraightOnesDoNot) {
  const BodyFitParams p;  // defaults: link 8 cm, >= 6 cells, r 0.05-0.6 m, RMS <= 8 cm, arc >= 60 deg
  std::vector<Vec2> pts = arc_points({3.0, 1.0}, 0.35, 120, 240, 20, 0.005, 3);  // the near side of a post
  const std::vector<Vec2> wall = arc_points({3.0, -60.0}, 60.0, 88, 92, 40, 0.0, 4);  // ~4 m of a straight wall
  const std::vector<Vec2> small = arc_points({5.0, 3.0}, 0.2, 0, 60, 4, 0.0, 5);        // too few cells
  pts.insert(pts.end(), wall.begin(), wall.end());
  pts.insert(pts.end(), small.begin(), small.end());
  const auto bodies = fit_bodies(as_cells(pts), {0.0, 0.0}, p);
  ASSERT_EQ(bodies.size(), 1u);
  EXPECT_NEAR(bodies[0].circle.c.x, 3.0, 0.02);
  EXPECT_NEAR(bodies[0].circle.c.y, 1.0, 0.02);
  EXPECT_NEAR(bodies[0].circle.r, 0.35, 0.02);
  EXPECT_TRUE(bodies[0].circle.transient);
  EXPECT_FALSE(bodies[0].circle.moves());
  EXPECT_EQ(bodies[0].cells, 20);
}

TEST(FitBodies, AcceptanceLimitsAreEachApplied) {
  const std::vector<CircleObstacle> cells = as_cells(arc_points({2.0, 0.0}, 0.3, 150, 210, 12, 0.0, 6));  // 60 deg
  BodyFitParams p;
  p.min_arc_deg = 50;
  EXPECT_EQ(fit_bodies(cells, {0, 0}, p).size(), 1u);
  p.min_arc_deg = 70;  // the cells cover 60 deg
  EXPECT_TRUE(fit_bodies(cells, {0, 0}, p).empty());
  p = BodyFitParams{};
  p.min_arc_deg = 50;
  p.max_r_m = 0.25;
  EXPECT_TRUE(fit_bodies(cells, {0, 0}, p).empty());
  p.max_r_m = 0.6;
  p.min_r_m = 0.35;
  EXPECT_TRUE(fit_bodies(cells, {0, 0}, p).empty());
  p.min_r_m = 0.05;
  p.min_cells = 13;
  EXPECT_TRUE(fit_bodies(cells, {0, 0}, p).empty());
  p.min_cells = 6;
  // a robot standing inside the fitted circle: the fit cannot be right
  EXPECT_TRUE(fit_bodies(cells, {2.05, 0.0}, p).empty());
  // noisy cells: RMS above the limit
  const auto noisy = as_cells(arc_points({2.0, 0.0}, 0.3, 120, 240, 24, 0.04, 7));
  p.max_rms_m = 0.01;
  EXPECT_TRUE(fit_bodies(noisy, {0, 0}, p).empty());
  p.max_rms_m = 0.1;
  EXPECT_EQ(fit_bodies(noisy, {0, 0}, p).size(), 1u);
}

TEST(FitBodies, GroupsAreSplitAtTheLinkDistance) {
  // Two posts 0.3 m apart (surface to surface): two bodies; with a link longer than the gap, one
  // group whose circle fails the RMS limit.
  std::vector<Vec2> pts = arc_points({2.0, -0.5}, 0.2, 120, 240, 15, 0.0, 8);
  const std::vector<Vec2> b = arc_points({2.0, 0.2}, 0.2, 120, 240, 15, 0.0, 9);
  pts.insert(pts.end(), b.begin(), b.end());
  BodyFitParams p;
  EXPECT_EQ(fit_bodies(as_cells(pts), {0, 0}, p).size(), 2u);
  p.link_m = 0.5;
  EXPECT_TRUE(fit_bodies(as_cells(pts), {0, 0}, p).empty());
}

TEST(FitBodies, ALongWallAlongYIsOneGroupWithoutABody) {
  // 2000 cells 2.5 cm apart on the line x = 1 (all with one x: the layout that makes an x-sorted sweep
  // compare all pairs) plus a post: one straight group (no circle) and the post's body.
  std::vector<Vec2> pts;
  for (int i = 0; i < 2000; ++i) pts.push_back({1.0, -25.0 + 0.025 * i});
  const std::vector<Vec2> post = arc_points({3.0, 0.0}, 0.3, 120, 240, 12, 0.0, 10);
  pts.insert(pts.end(), post.begin(), post.end());
  const auto bodies = fit_bodies(as_cells(pts), {0.0, 0.0}, BodyFitParams{});
  ASSERT_EQ(bodies.size(), 1u);
  EXPECT_NEAR(bodies[0].circle.c.x, 3.0, 1e-6);
  EXPECT_NEAR(bodies[0].circle.r, 0.3, 1e-6);
  EXPECT_EQ(bodies[0].cells, 12);
}

// A 64-column camera at the origin looking along +x that sees free space to free_m in every column.
CameraScan forward_scan(double free_m) {
  CameraScan s;
  s.pose = {0, 0, 0};
  s.focal_px = 40.0;
  s.cx = 31.5;
  s.min_range_m = 0.3;
  s.free_range_m.assign(64, free_m);
  return s;
}

TEST(ObstacleMap, SeenFreeShareCountsTheCellsTheCameraSawThrough) {
  ObstacleMap map;
  const CameraScan s = forward_scan(3.0);  // every column sees free space to 3 m
  for (int k = 0; k < 3; ++k) map.integrate(s);  // log-odds -1.2 there
  // A disc inside the seen-free range: all free; one beyond it: none; straddling: part.
  EXPECT_NEAR(map.seen_free_share({2.0, 0.0}, 0.3, -0.4), 1.0, 1e-9);
  EXPECT_NEAR(map.seen_free_share({5.0, 0.0}, 0.3, -0.4), 0.0, 1e-9);
  const double part = map.seen_free_share({3.0, 0.0}, 0.3, -0.4);
  EXPECT_GT(part, 0.2);
  EXPECT_LT(part, 0.8);
  EXPECT_NEAR(ObstacleMap{}.seen_free_share({0, 0}, 1.0, -0.4), 0.0, 1e-12);  // before any scan
}

TEST(ObstacleMap, VacatedShareCountsOnlyTheCellsAnObstacleLeft) {
  // An obstacle stood at (2, 0.4) (its front surface hit for 3 frames), then moved to (2, -0.4) and the camera
  // sees through its old place for 4 frames (log-odds 3 x 0.85 - 4 x 0.4 < -0.4 only where it was never hit).
  ObstacleMap map;
  CameraScan s = forward_scan(1.7);  // the old body's front at x = 1.7 .. its back hidden
  for (int k = 0; k < 3; ++k) {
    s.hits.clear();
    for (int i = -5; i <= 5; ++i) s.hits.push_back({1.72, 0.4 + 0.05 * i});
    map.integrate(s);
  }
  s.hits.clear();
  s.free_range_m.assign(64, 3.0);  // it left: free to 3 m everywhere
  for (int k = 0; k < 4; ++k) map.integrate(s);
  int cells = 0;
  const double left = map.seen_free_share_outside({2.0, 0.4}, 0.3, {2.0, -0.4}, 0.3, -0.4, cells);
  EXPECT_GT(cells, 100);  // pi 0.3^2 / 0.05^2 = 113 cells, none inside the present disc
  EXPECT_GT(left, 0.8);   // all but the cells hit three times (log-odds 0.95 after four misses)
  EXPECT_LT(left, 1.0);
  // The present disc covering the earlier one: no cells left, no evidence.
  EXPECT_EQ(map.seen_free_share_outside({2.0, 0.4}, 0.3, {2.0, 0.45}, 0.4, -0.4, cells), 0.0);
  EXPECT_EQ(cells, 0);
  // A place beyond what the camera saw free (behind a standing obstacle): cells, but none seen through.
  EXPECT_EQ(map.seen_free_share_outside({4.0, 0.0}, 0.3, {4.0, 0.8}, 0.3, -0.4, cells), 0.0);
  EXPECT_GT(cells, 100);
}

}  // namespace
}  // namespace fs::robot
