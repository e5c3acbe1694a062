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

TEST(DetectionMatcherParams, SegmentationRoundsOfTheDetectionConsumersAreTheirOwn) {
  // The defaults (session 44): match / eval / bench start coarse (1 + 1 rounds), detection and the robot keep 0 + 4.
  const fs::Config def = fs::parse_config("", "t");
  EXPECT_EQ(def.matcher.seg.coarse_iterations, 1);
  EXPECT_EQ(def.matcher.seg.iterations, 1);
  const fs::MatcherParams d = detection_matcher_params(def.matcher, def.values);
  EXPECT_EQ(d.seg.coarse_iterations, 0);
  EXPECT_EQ(d.seg.iterations, 4);

  // -1: as [segmentation].
  const fs::Config follow = fs::parse_config(
      "[segmentation]\ncoarse_iterations = 2\niterations = 3\n[detect]\nmatcher_coarse_iterations = -1\nmatcher_iterations = -1\n",
      "t");
  const fs::MatcherParams f = detection_matcher_params(follow.matcher, follow.values);
  EXPECT_EQ(f.seg.coarse_iterations, 2);
  EXPECT_EQ(f.seg.iterations, 3);

  // 0 full-resolution rounds is refused with the field and its valid values named.
  const fs::Config zero = fs::parse_config("[detect]\nmatcher_iterations = 0\n", "t");
  try {
    (void)detection_matcher_params(zero.matcher, zero.values);
    FAIL() << "matcher_iterations = 0 was accepted";
  } catch (const fs::UserError& e) {
    EXPECT_NE(std::string(e.what()).find("detect.matcher_iterations"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("1 to 20"), std::string::npos) << e.what();
  }
}

TEST(DetectionMatcherParams, NmiCandidatesOfTheDetectionConsumersFollowCostUnlessSet) {
  const fs::Config def = fs::parse_config("[cost]\nnmi_candidates = 2\n", "t");
  EXPECT_EQ(detection_matcher_params(def.matcher, def.values).cost.nmi_candidates, 2);  // -1: as [cost]
  const fs::Config own = fs::parse_config("[cost]\nnmi_candidates = 2\n[detect]\nmatcher_nmi_candidates = 8\n", "t");
  EXPECT_EQ(detection_matcher_params(own.matcher, own.values).cost.nmi_candidates, 8);
  EXPECT_EQ(own.matcher.cost.nmi_candidates, 2);  // match / eval / bench follow [cost] alone
}

}  // namespace
