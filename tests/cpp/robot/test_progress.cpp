// ProgressMonitor ([loop] stuck_after_s): when a robot counts as stuck, and when it stops.
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

}  // namespace
}  // namespace fs::robot
