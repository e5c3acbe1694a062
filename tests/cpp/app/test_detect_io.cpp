// The matcher settings the detection consumers (detect, detect-eval, the robot loop) run with:
// [detect] input, matcher_boundary and matcher_subpixel_every_segment (docs/detection.md "Input map").
#include <gtest/gtest.h>

#include "config.hpp"
#include "detect_io.hpp"

namespace {

using fs::app::detection_matcher_params;

TEST(DetectionMatcherParams, SparseInputSkipsDensifyAndMatcherBoundaryTurnsTheRefinementOn) {
  const fs::Config plain = fs::parse_config("[detect]\nmatcher_boundary = false\n", "t");
  ASSERT_TRUE(plain.matcher.densify.enabled);
  ASSERT_FALSE(plain.matcher.boundary.enabled);
  const fs::MatcherParams p = detection_matcher_params(plain.matcher, plain.values);
  EXPECT_FALSE(p.densify.enabled);  // the ESR map is what detection reads
  EXPECT_FALSE(p.boundary.enabled);

  const fs::Config on = fs::parse_config("[detect]\nmatcher_boundary = true\n[boundary]\nwindow = 5\n", "t");
  const fs::MatcherParams q = detection_matcher_params(on.matcher, on.values);
  EXPECT_TRUE(q.boundary.enabled);
  EXPECT_EQ(q.boundary.window, 5);  // the [boundary] parameters are kept
  EXPECT_FALSE(on.matcher.boundary.enabled);  // match / eval / bench follow [boundary] enabled alone

  const fs::Config dense = fs::parse_config("[detect]\ninput = \"dense\"\nmatcher_boundary = false\n[boundary]\nenabled = true\n", "t");
  const fs::MatcherParams d = detection_matcher_params(dense.matcher, dense.values);
  EXPECT_TRUE(d.densify.enabled);
  EXPECT_TRUE(d.boundary.enabled);  // either switch turns it on
}

TEST(DetectionMatcherParams, MatcherSubpixelEverySegmentTurnsTheRuleOnForDetectionOnly) {
  const fs::Config off = fs::parse_config("[detect]\nmatcher_subpixel_every_segment = false\n", "t");
  ASSERT_FALSE(off.matcher.cost.subpixel_every_segment);
  EXPECT_FALSE(detection_matcher_params(off.matcher, off.values).cost.subpixel_every_segment);

  const fs::Config on = fs::parse_config("[detect]\nmatcher_subpixel_every_segment = true\n", "t");
  EXPECT_TRUE(detection_matcher_params(on.matcher, on.values).cost.subpixel_every_segment);
  EXPECT_FALSE(on.matcher.cost.subpixel_every_segment);  // match / eval / bench follow [cost] alone

  const fs::Config cost = fs::parse_config("[cost]\nsubpixel_every_segment = true\n[detect]\nmatcher_subpixel_every_segment = false\n", "t");
  EXPECT_TRUE(detection_matcher_params(cost.matcher, cost.values).cost.subpixel_every_segment);  // either switch
}

}  // namespace
