// Fragment merging by complete linkage and attaching (session 8, docs/detection.md "(e) Fragment merging"):
// a small fragment at an intermediate depth no longer chains two obstacles 15 % apart, and a fragment the
// span limit refuses still joins the obstacle whose median it is near.
#include <gtest/gtest.h>

#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

void fill(ImageI32& comp, ImageI16& disp, int label, int x0, int y0, int x1, int y1, int q4) {
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) comp.at(x, y) = label, disp.at(x, y) = std::int16_t(q4);
}

DetectParams isolated() {  // only fragment merging acts
  DetectParams p;
  p.min_area_px = 10;
  p.min_area_m2 = 0.0;
  p.min_height_m = 0.0;
  p.max_distance_m = 0.0;
  p.merge_gap_px = 8;
  p.merge_max_rel_disparity = 0.1;
  p.merge_edge_rel_disparity = 0.0;
  p.merge_occluded_max_gap_px = 0;
  p.contain_min_inside = 0.0;
  return p;
}

const StereoCalib kCalib{200.0, 50.0, 30.0, 0.1, 0.5, 0.0};

TEST(DetectLinkage, BridgeFragmentNoLongerChainsTwoObstacles) {
  // A at d = 20 px (Q4 320), B at 17 px (272, 15 % farther), 10 columns apart (farther than merge_gap_px), and
  // a 6x11 bridge C at 18.5 px (296) between them: within 10 % of both (7.5 % and 8.1 %).
  ImageI32 comp(100, 60, 0);
  ImageI16 disp(100, 60, kInvalidDisp);
  fill(comp, disp, 1, 10, 10, 39, 49, 320);
  fill(comp, disp, 2, 42, 20, 47, 30, 296);
  fill(comp, disp, 3, 50, 10, 79, 39, 272);
  DetectParams p = isolated();
  p.merge_group_max_rel = 0.0;  // single linkage: A - C - B is one chain
  auto o = detect::measure_obstacles(comp, 3, disp, kCalib, p, nullptr);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_EQ(o[0].x0, 10);
  EXPECT_EQ(o[0].x1, 79);
  p.merge_group_max_rel = 0.12;  // A + C spans 7.5 %; adding B would span 15 %: refused
  p.merge_attach = true;         // and B (15 % from the group's median) does not attach
  ImageI32 labels;
  o = detect::measure_obstacles(comp, 3, disp, kCalib, p, &labels);
  ASSERT_EQ(o.size(), 2u);
  EXPECT_EQ(o[0].x0, 10);  // nearest first: A with the bridge
  EXPECT_EQ(o[0].x1, 47);
  EXPECT_EQ(o[0].pixel_count, 1200 + 66);
  EXPECT_EQ(o[0].disparity_q4, 320);
  EXPECT_EQ(o[1].x0, 50);
  EXPECT_EQ(o[1].x1, 79);
  EXPECT_EQ(o[1].disparity_q4, 272);
  EXPECT_EQ(labels.at(45, 25), 1);
  EXPECT_EQ(labels.at(60, 20), 2);
  p.merge_group_max_rel = 0.16;  // a span limit above the 15 %: one chain again
  EXPECT_EQ(detect::measure_obstacles(comp, 3, disp, kCalib, p, nullptr).size(), 1u);
}

TEST(DetectLinkage, FragmentRefusedBySpanAttachesToNearestGroup) {
  // A at Q4 320 (1200 px); K at 300 (6.25 % from A) and H at 344 (7 % from A) beside it; K and H are 12.8 %
  // apart. The closest pair A-K joins first; A-H would make the span 300..344 = 12.8 % > 12 %: refused.
  // H's median is within 10 % of the group's (320): it attaches.
  ImageI32 comp(100, 60, 0);
  ImageI16 disp(100, 60, kInvalidDisp);
  fill(comp, disp, 1, 10, 10, 39, 49, 320);
  fill(comp, disp, 2, 42, 20, 45, 29, 300);
  fill(comp, disp, 3, 44, 32, 49, 41, 344);
  DetectParams p = isolated();
  p.merge_group_max_rel = 0.12;
  p.merge_attach = false;
  auto o = detect::measure_obstacles(comp, 3, disp, kCalib, p, nullptr);
  ASSERT_EQ(o.size(), 2u);
  EXPECT_EQ(o[0].pixel_count, 60);  // H alone, nearest
  EXPECT_EQ(o[1].pixel_count, 1240);
  p.merge_attach = true;
  o = detect::measure_obstacles(comp, 3, disp, kCalib, p, nullptr);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_EQ(o[0].pixel_count, 1300);
  EXPECT_EQ(o[0].x1, 49);
  p.merge_group_max_rel = 0.0;  // single linkage joins all three directly
  EXPECT_EQ(detect::measure_obstacles(comp, 3, disp, kCalib, p, nullptr).size(), 1u);
}

}  // namespace
}  // namespace fs
