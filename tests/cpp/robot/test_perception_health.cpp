// Perception health failsafe (robot::PerceptionMonitor, perception_fault, image_stats): a blind or
// frozen camera must stop the robot, debounced both ways; healthy frames never do.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "fuzzystereo/robot/perception_health.hpp"

namespace fs::robot {
namespace {

FrameHealth healthy() {
  FrameHealth h;
  h.contrast_left = h.contrast_right = 40.0;
  h.noise_left = h.noise_right = 1.5;
  h.valid_pct = 45.0;
  return h;
}

TEST(PerceptionHealth, ImageStatsMatchesAPlainComputation) {
  const int w = 37, h = 23;
  std::vector<std::uint8_t> img(std::size_t(w) * h);
  std::mt19937 rng(3);
  for (auto& v : img) v = static_cast<std::uint8_t>(rng() % 256);
  for (int step : {1, 4}) {
    double s = 0, s2 = 0;
    int n = 0;
    for (int y = 0; y < h; y += step)
      for (int x = 0; x < w; x += step) {
        const double v = img[std::size_t(y) * w + x];
        s += v;
        s2 += v * v;
        ++n;
      }
    const double mean = s / n;
    const ImageStats st = image_stats(img.data(), w, h, std::size_t(w), step);
    EXPECT_NEAR(st.stddev, std::sqrt(s2 / n - mean * mean), 1e-9) << "step " << step;
  }
  // the hash sees the sampled pixels only, and every change among them
  const auto h0 = image_stats(img.data(), w, h, std::size_t(w), 4).hash;
  img[1] ^= 1;  // (1, 0): not sampled at step 4
  EXPECT_EQ(image_stats(img.data(), w, h, std::size_t(w), 4).hash, h0);
  img[4] ^= 1;  // (4, 0): sampled
  EXPECT_NE(image_stats(img.data(), w, h, std::size_t(w), 4).hash, h0);
  // a constant image has no contrast
  std::vector<std::uint8_t> flat(std::size_t(w) * h, 77);
  EXPECT_EQ(image_stats(flat.data(), w, h, std::size_t(w)).stddev, 0.0);
}

TEST(PerceptionHealth, EachTestNamesTheCameraAndTheLimit) {
  const PerceptionHealthParams p;
  EXPECT_EQ(perception_fault(healthy(), p), "");
  FrameHealth h = healthy();
  h.contrast_right = 0.3;
  h.noise_right = 0.0;
  EXPECT_EQ(perception_fault(h, p), "right camera blind: contrast 0.3 < 2 grey levels");
  // a covered lens: all its variance is sensor noise (measured in the simulator: std 3.0, noise 2.97)
  // and the views match only by chance (8.7 %)
  h = healthy();
  h.contrast_left = 3.0;
  h.noise_left = 2.97;
  h.valid_pct = 8.7;
  EXPECT_EQ(perception_fault(h, p),
            "left camera blind: only noise (contrast 3.0, noise 3.0 grey levels) and 8.7 % of the pixels match (< 20 %)");
  // a noise-like texture (random dots: std 74, "noise" 74) that the other view matches is a scene
  h.contrast_left = h.noise_left = 74.0;
  h.valid_pct = 80.0;
  EXPECT_EQ(perception_fault(h, p), "");
  h = healthy();
  h.contrast_left = 3.0;
  h.noise_left = 0.0;  // without a noise estimate the covered lens passes the contrast tests ...
  h.valid_pct = 8.7;
  EXPECT_EQ(perception_fault(h, p), "");
  h.valid_pct = 1.5;   // ... and the views' mismatch is the backstop
  EXPECT_EQ(perception_fault(h, p), "views do not match: 1.5 % of the pixels have a disparity (< 2 %)");
  h = healthy();
  h.same_right = 5;
  EXPECT_EQ(perception_fault(h, p), "right camera frozen: 6 identical frames in a row");
  h.same_right = 4;
  EXPECT_EQ(perception_fault(h, p), "");
  PerceptionHealthParams off = p;
  off.frozen_frames = 0;
  h.same_left = 1000;
  EXPECT_EQ(perception_fault(h, off), "");
}

TEST(PerceptionHealth, StopsAfterTripFramesAndDrivesAgainAfterClearFrames) {
  PerceptionHealthParams p;
  p.trip_frames = 3;
  p.clear_frames = 5;
  PerceptionMonitor m(p);
  FrameHealth blind = healthy();
  blind.contrast_left = 0.0;
  blind.noise_left = 0.0;
  for (int i = 0; i < 10; ++i) EXPECT_FALSE(m.update(healthy()));
  // two faulty frames and a healthy one: no stop (debounce), and the count starts again
  EXPECT_FALSE(m.update(blind));
  EXPECT_FALSE(m.update(blind));
  EXPECT_FALSE(m.update(healthy()));
  EXPECT_FALSE(m.update(blind));
  EXPECT_FALSE(m.update(blind));
  EXPECT_TRUE(m.update(blind));  // the third in a row
  EXPECT_EQ(m.trips(), 1);
  EXPECT_FALSE(m.fault().empty());
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(m.update(healthy())) << i;  // still stopped
  EXPECT_TRUE(m.update(blind));  // a relapse restarts the healthy count
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(m.update(healthy()));
  EXPECT_FALSE(m.update(healthy()));  // the fifth healthy frame in a row
  EXPECT_TRUE(m.fault().empty());
  EXPECT_EQ(m.trips(), 1);
}

TEST(PerceptionHealth, StartsStoppedUntilStartupFramesAreHealthy) {
  PerceptionHealthParams p;
  p.startup_frames = 2;
  PerceptionMonitor m(p);
  FrameHealth blind = healthy();
  blind.valid_pct = 0.5;
  EXPECT_FALSE(m.started());
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(m.update(blind)) << i;  // a camera covered at power-on
  EXPECT_EQ(m.trips(), 0);  // not a trip: the robot never drove
  EXPECT_TRUE(m.update(healthy()));
  EXPECT_FALSE(m.update(healthy()));  // the second healthy frame in a row
  EXPECT_TRUE(m.started());
  // from now on the trip / clear rules of a running robot apply
  for (int i = 0; i < p.trip_frames - 1; ++i) EXPECT_FALSE(m.update(blind));
  EXPECT_TRUE(m.update(blind));
  EXPECT_EQ(m.trips(), 1);
}

TEST(PerceptionHealth, DisabledMonitorNeverStops) {
  PerceptionHealthParams p;
  p.enabled = false;
  PerceptionMonitor m(p);
  FrameHealth blind = healthy();
  blind.valid_pct = 0.0;
  for (int i = 0; i < 20; ++i) EXPECT_FALSE(m.update(blind));
  EXPECT_EQ(m.trips(), 0);
}

TEST(PerceptionHealth, FrozenCounterCountsRepeats) {
  FrozenCounter c;
  EXPECT_EQ(c.update(7), 0);
  EXPECT_EQ(c.update(7), 1);
  EXPECT_EQ(c.update(7), 2);
  EXPECT_EQ(c.update(8), 0);
  EXPECT_EQ(c.update(8), 1);
}

}  // namespace
}  // namespace fs::robot
