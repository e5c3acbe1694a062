// ProgressMonitor ([loop] stuck_after_s): when a robot counts as stuck, and when it stops;
// GiveUpMonitor ([loop] give_up_after_s): when it stops for good.
#include <gtest/gtest.h>

#include "fuzzystereo/robot/progress.hpp"

namespace fs::robot {
namespace {

constexpr std::int64_t kS = 1'000'000'000;

TEST(Progress, NeverStuckWhenOff) {
  ProgressMonitor m({0.0, 0.3, 1.0});
  for (int i = 0; i < 1000; ++i) EXPECT_FALSE(m.update(i * kS, 5.0));
}

TEST(Progress, StuckAfterTheTimeWithoutProgressAndNotBefore) {
  ProgressMonitor m({12.0, 0.3, 1.0});
  // Steady progress of 0.125 m/s (exact in binary): a new best every 3 s, never stuck.
  for (int i = 0; i <= 40; ++i) EXPECT_FALSE(m.update(i * kS, 6.0 - 0.125 * i)) << i;
  EXPECT_DOUBLE_EQ(m.best_m(), 1.125);  // set at t = 39 s
  // Wandering within 0.3 m of the best from t = 41 s on.
  for (int i = 41; i <= 51; ++i) EXPECT_FALSE(m.update(i * kS, 1.2 + 0.05 * (i % 3))) << i;
  EXPECT_TRUE(m.update(52 * kS, 1.2));  // 13 s after the best
  EXPECT_DOUBLE_EQ(m.best_m(), 1.125);
}

TEST(Progress, SmallStepsBelowTheProgressDoNotResetTheTimer) {
  ProgressMonitor m({10.0, 0.3, 1.0});
  m.update(0, 5.0);
  // 0.2 m per 6 s: below 0.3 m since the last best, until 0.3 m are reached at t = 9 s.
  EXPECT_FALSE(m.update(6 * kS, 4.8));
  EXPECT_FALSE(m.update(9 * kS, 4.69));  // 0.31 m: new best at 9 s
  EXPECT_FALSE(m.update(19 * kS, 4.6));
  EXPECT_TRUE(m.update(19 * kS + 1, 4.6));
}

TEST(Progress, TheModeHoldsUntilTheRobotIsExitCloserThanBefore) {
  ProgressMonitor m({5.0, 0.3, 1.0});
  m.update(0, 4.0);
  EXPECT_TRUE(m.update(6 * kS, 4.5));
  // Approaching the gap: 0.5 m better than the best (a new best), still stuck.
  EXPECT_TRUE(m.update(7 * kS, 3.5));
  EXPECT_TRUE(m.update(8 * kS, 3.1));
  // Through it: more than 1 m closer than the best when the mode began (4.0).
  EXPECT_FALSE(m.update(9 * kS, 2.9));
  // And a new timer from the new best.
  EXPECT_FALSE(m.update(13 * kS, 3.2));
  EXPECT_TRUE(m.update(15 * kS, 3.2));
}

// [loop] give_up_after_s: stop for good after no progress with a blocked plan since the last progress.
TEST(GiveUp, NeverWhenOff) {
  GiveUpMonitor m({0.0, 0.3});
  for (int i = 0; i < 1000; ++i) EXPECT_FALSE(m.update(i * kS, 5.0, true));
}

TEST(GiveUp, NeedsBothTheTimeWithoutProgressAndABlockedPlanSinceTheBest) {
  GiveUpMonitor m({15.0, 0.3});
  EXPECT_FALSE(m.update(0, 5.0, false));  // best 5.0 at t = 0
  // 40 s of wandering without progress, the planner always finding a path: no.
  for (int i = 1; i <= 40; ++i) EXPECT_FALSE(m.update(i * kS, 5.1, false)) << i;
  // One blocked step: the timer already runs from t = 0, so the rule holds at once.
  EXPECT_TRUE(m.update(41 * kS, 5.1, true));
  // It latches, whatever comes next.
  EXPECT_TRUE(m.update(42 * kS, 1.0, false));
  EXPECT_TRUE(m.given_up());
}

TEST(GiveUp, ProgressClearsTheBlockedStepAndRestartsTheTimer) {
  GiveUpMonitor m({15.0, 0.3});
  m.update(0, 5.0, false);
  EXPECT_FALSE(m.update(2 * kS, 5.0, true));  // blocked 2 s after the best: the time is not up
  // 0.4 m closer at t = 10 s: a new best, the blocked step before it no longer counts.
  EXPECT_FALSE(m.update(10 * kS, 4.6, false));
  EXPECT_FALSE(m.update(30 * kS, 4.5, false));  // 20 s, but no blocked step since the best
  EXPECT_TRUE(m.update(31 * kS, 4.5, true));    // blocked, 21 s after the best: gives up
}

TEST(GiveUp, GivesUpExactlyWhenTheTimeIsReached) {
  GiveUpMonitor m({15.0, 0.3});
  m.update(0, 5.0, true);  // blocked on the first step (the best is set on it)
  EXPECT_FALSE(m.update(15 * kS - 1, 4.9, false));
  EXPECT_TRUE(m.update(15 * kS, 4.9, false));
}

// [loop] stuck_keep_unseen: while stuck, only tracks the camera looks at lose their circles.
TEST(Progress, StuckDropsCirclesOnlyInViewWithKeepUnseen) {
  const Pose2D robot{1.0, 2.0, M_PI / 2};  // facing +y
  const double half_fov = 50.0 * M_PI / 180.0;
  const Vec2 ahead{1.0, 3.0}, left_front{0.4, 3.0}, beside{0.0, 2.1}, behind{1.1, 1.0};
  // Not stuck: nothing is dropped, whatever the mode.
  for (bool keep : {false, true})
    for (Vec2 p : {ahead, beside, behind}) EXPECT_FALSE(stuck_drops_track_circle(false, keep, robot, p, half_fov));
  // Stuck, session-23 rule: every track's circle goes.
  for (Vec2 p : {ahead, left_front, beside, behind}) EXPECT_TRUE(stuck_drops_track_circle(true, false, robot, p, half_fov));
  // Stuck, keep_unseen: ahead (0 deg) and left-front (31 deg) are in view and go; beside (84 deg)
  // and behind (174 deg) keep theirs.
  EXPECT_TRUE(stuck_drops_track_circle(true, true, robot, ahead, half_fov));
  EXPECT_TRUE(stuck_drops_track_circle(true, true, robot, left_front, half_fov));
  EXPECT_FALSE(stuck_drops_track_circle(true, true, robot, beside, half_fov));
  EXPECT_FALSE(stuck_drops_track_circle(true, true, robot, behind, half_fov));
  // The view edge, across the +-pi wrap: a robot facing -x (yaw pi) sees (-1, +-0.5) at 26.6 deg
  // either side, and not (0, +-2) at 63 deg.
  const Pose2D west{0.0, 0.0, M_PI};
  EXPECT_TRUE(stuck_drops_track_circle(true, true, west, {-1.0, 0.5}, half_fov));
  EXPECT_TRUE(stuck_drops_track_circle(true, true, west, {-1.0, -0.5}, half_fov));
  EXPECT_FALSE(stuck_drops_track_circle(true, true, west, {-1.0, 2.0}, half_fov));
  EXPECT_FALSE(stuck_drops_track_circle(true, true, west, {-1.0, -2.0}, half_fov));
}

TEST(Progress, NearTrackCircleOverlappingTheRobotFollowsTheOverlapRule) {
  // docs/robot.md "Session 41": robot radius 0.15 m, a track of radius 0.2 m. Clear of the robot's
  // disc (0.5 m > 0.35 m) the circle is given whatever the rule; overlapping (0.3 m) it is dropped,
  // kept, or kept only without static support.
  const double rr = 0.15, tr = 0.2;
  for (auto mode : {NearTrackOverlap::kDrop, NearTrackOverlap::kKeep, NearTrackOverlap::kKeepUnsupported}) {
    const NearTrackRule rule{1.0, 1.5, 0.04, mode};
    EXPECT_TRUE(near_track_circle(rule, 0.2, 0.5, 0.3, tr, rr, false));
    EXPECT_TRUE(near_track_circle(rule, 0.2, 0.5, 0.3, tr, rr, true));
    // the other conditions hold for every rule: too old, too far, too slow
    EXPECT_FALSE(near_track_circle(rule, 1.2, 0.5, 0.3, tr, rr, false));
    EXPECT_FALSE(near_track_circle(rule, 0.2, 1.6, 0.3, tr, rr, false));
    EXPECT_FALSE(near_track_circle(rule, 0.2, 0.5, 0.03, tr, rr, false));
    EXPECT_FALSE(near_track_circle(rule, 1.2, 0.3, 0.3, tr, rr, false));
  }
  const NearTrackRule drop{1.0, 1.5, 0.04, NearTrackOverlap::kDrop}, keep{1.0, 1.5, 0.04, NearTrackOverlap::kKeep},
      unsup{1.0, 1.5, 0.04, NearTrackOverlap::kKeepUnsupported};
  EXPECT_FALSE(near_track_circle(drop, 0.2, 0.3, 0.3, tr, rr, false));
  EXPECT_FALSE(near_track_circle(drop, 0.2, 0.35, 0.3, tr, rr, false));  // touching counts as overlapping
  EXPECT_TRUE(near_track_circle(keep, 0.2, 0.3, 0.3, tr, rr, false));
  EXPECT_TRUE(near_track_circle(keep, 0.2, 0.3, 0.3, tr, rr, true));
  EXPECT_TRUE(near_track_circle(unsup, 0.2, 0.3, 0.3, tr, rr, false));
  EXPECT_FALSE(near_track_circle(unsup, 0.2, 0.3, 0.3, tr, rr, true));
}

TEST(Progress, MovingTestVerdictsInOrderAndTheDirectionCheckNearTheRobot) {
  // A track that passes every condition: 6 hits, 0.3 m/s along +x, measured now, travelled 1 m along +x in 4 s.
  MovingTestParams p;  // min_hits 4, 0.04 m/s, 8 s, 0.3 m, no sigmas, no window, direction checked everywhere
  MovingTestInput in;
  in.hits = 6, in.vel = {0.3, 0.0}, in.age_s = 0.0, in.travel = {1.0, 0.0}, in.life_s = 4.0, in.robot_dist_m = 1.0;
  EXPECT_STREQ(moving_test(p, in), "mover");
  // each condition on its own, and the first one failing is the one named
  MovingTestInput t = in;
  t.static_support = true, t.hits = 1;
  EXPECT_STREQ(moving_test(p, t), "static support");
  t.static_measurement = true;  // the measurement-level reason is named first
  EXPECT_STREQ(moving_test(p, t), "static measurement");
  t = in, t.hits = 3;
  EXPECT_STREQ(moving_test(p, t), "few hits");
  t = in, t.vel = {0.03, 0.0};
  EXPECT_STREQ(moving_test(p, t), "slow");
  t = in, t.age_s = 9.0;
  EXPECT_STREQ(moving_test(p, t), "old");
  t = in, t.travel = {0.25, 0.0};
  EXPECT_STREQ(moving_test(p, t), "short travel");
  t = in, t.life_s = 30.0;  // 1 m in 30 s: below 0.04 m/s on average
  EXPECT_STREQ(moving_test(p, t), "short travel");
  MovingTestParams ps = p;
  ps.travel_sigmas = 3.0;
  t = in, t.end_var_m2 = 0.25;  // std 0.5 m: 3 sigma = 1.5 m > 1 m travelled
  EXPECT_STREQ(moving_test(ps, t), "travel within noise");
  // the direction: velocity 60 deg off the whole-life travel (cos 0.5 < 0.7) fails; 40 deg (cos 0.77) passes
  t = in, t.vel = {0.15, 0.26};
  EXPECT_STREQ(moving_test(p, t), "direction");
  t = in, t.vel = {0.23, 0.193};
  EXPECT_STREQ(moving_test(p, t), "mover");
  // ... judged on the recent travel with a window (the mover turned): the same velocity passes
  MovingTestParams pw = p;
  pw.window_s = 3.0;
  t = in, t.vel = {0.0, 0.3}, t.recent_travel = {0.05, 0.6};
  EXPECT_STREQ(moving_test(p, t), "direction");
  EXPECT_STREQ(moving_test(pw, t), "mover");
  t.recent_travel = {0.05, 0.05};  // recent travel below window_travel_m: the whole-life travel decides
  EXPECT_STREQ(moving_test(pw, t), "direction");
  // direction_near_m (session 41): within it the direction check is skipped, the other conditions stay
  MovingTestParams pn = p;
  pn.direction_near_m = 1.5;
  t = in, t.vel = {0.0, 0.3}, t.robot_dist_m = 1.2;
  EXPECT_STREQ(moving_test(p, t), "direction");
  EXPECT_STREQ(moving_test(pn, t), "mover");
  t.robot_dist_m = 1.6;
  EXPECT_STREQ(moving_test(pn, t), "direction");
  t.robot_dist_m = 1.2, t.travel = {0.2, 0.0};
  EXPECT_STREQ(moving_test(pn, t), "short travel");
  t = in, t.robot_dist_m = 0.5, t.static_support = true;
  EXPECT_STREQ(moving_test(pn, t), "static support");
}

TEST(Progress, MovingTestVacatedPlaceOverridesOnlyTheTravelConditions) {
  MovingTestParams p;
  p.vacated_share = 0.3, p.vacated_near_m = 3.0, p.vacated_min_cells = 8;
  MovingTestInput in;
  in.hits = 6, in.vel = {0.3, 0.0}, in.age_s = 0.0, in.travel = {0.1, 0.0}, in.life_s = 4.0, in.robot_dist_m = 1.0;
  EXPECT_STREQ(moving_test(p, in), "short travel");  // no evidence yet
  in.vacated = 0.5, in.vacated_cells = 20;
  EXPECT_STREQ(moving_test(p, in), "mover");
  MovingTestParams off = p;
  off.vacated_share = 0.0;
  EXPECT_STREQ(moving_test(off, in), "short travel");  // off: today's test
  MovingTestInput t = in;
  t.vacated_cells = 7;  // too few cells left
  EXPECT_STREQ(moving_test(p, t), "short travel");
  t = in, t.vacated = 0.29;  // below the share
  EXPECT_STREQ(moving_test(p, t), "short travel");
  t = in, t.robot_dist_m = 3.5;  // too far from the robot
  EXPECT_STREQ(moving_test(p, t), "short travel");
  t = in, t.travel = {1.0, 0.0}, t.vel = {0.0, 0.3};  // the direction check fails: overridden too
  EXPECT_STREQ(moving_test(off, t), "direction");
  EXPECT_STREQ(moving_test(p, t), "mover");
  p.travel_sigmas = 3.0;
  t = in, t.travel = {1.0, 0.0}, t.end_var_m2 = 0.25;
  EXPECT_STREQ(moving_test(p, t), "mover");  // "travel within noise" overridden
  // The other conditions are not.
  t = in, t.hits = 3;
  EXPECT_STREQ(moving_test(p, t), "few hits");
  t = in, t.vel = {0.03, 0.0};
  EXPECT_STREQ(moving_test(p, t), "slow");
  t = in, t.age_s = 9.0;
  EXPECT_STREQ(moving_test(p, t), "old");
  t = in, t.static_support = true;
  EXPECT_STREQ(moving_test(p, t), "static support");
  t = in, t.static_measurement = true;
  EXPECT_STREQ(moving_test(p, t), "static measurement");
}

}  // namespace
}  // namespace fs::robot
