// Fragment merging by complete linkage and attaching (session 8, docs/detection.md "(e) Fragment merging"):
// a small fragment at an intermediate depth no longer chains two obstacles 15 % apart, and a fragment the
// span limit refuses still joins the obstacle whose median it is near. No depth bridges (session 10): with
// single linkage a small fragment may close a gap in the image between two large components, not a gap in depth.
#include <gtest/gtest.h>

#include <algorithm>

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
  // plain single linkage and no later rules (the defaults since session 49 have them on; the tests below
  // switch each on where they test it)
  p.merge_gap_vertical_px = 8;
  p.merge_bridge_max_px = 0;
  p.merge_bridge_max_overlap = 1.0;
  p.seam_min_step = 0.0;
  p.inside_drop_min_share = 0.0;
  p.side_face_max_rel = 0.0;
  return p;
}

const StereoCalib kCalib{200.0, 50.0, 30.0, 0.1, 0.5, 0.0};

// The bridge scene: A at d = 20 px (Q4 320, 1200 px), B at 17 px (272, 900 px, 15 % farther), 10 columns
// apart (farther than merge_gap_px), and a 6x11 bridge C at 18.5 px (296, 66 px) between them: within 10 %
// of both (7.5 % and 8.1 %).
struct BridgeScene {
  ImageI32 comp{100, 60, 0};
  ImageI16 disp{100, 60, kInvalidDisp};
  BridgeScene() {
    fill(comp, disp, 1, 10, 10, 39, 49, 320);
    fill(comp, disp, 2, 42, 20, 47, 30, 296);
    fill(comp, disp, 3, 50, 10, 79, 39, 272);
  }
};

// A with the bridge, and B apart (nearest first).
void expect_bridge_joins_a_only(const std::vector<Obstacle>& o, const ImageI32& labels) {
  ASSERT_EQ(o.size(), 2u);
  EXPECT_EQ(o[0].x0, 10);
  EXPECT_EQ(o[0].x1, 47);
  EXPECT_EQ(o[0].pixel_count, 1200 + 66);
  EXPECT_EQ(o[0].disparity_q4, 320);
  EXPECT_EQ(o[1].x0, 50);
  EXPECT_EQ(o[1].x1, 79);
  EXPECT_EQ(o[1].pixel_count, 900);
  EXPECT_EQ(o[1].disparity_q4, 272);
  EXPECT_EQ(labels.at(45, 25), 1);
  EXPECT_EQ(labels.at(60, 20), 2);
}

TEST(DetectLinkage, BridgeFragmentNoLongerChainsTwoObstacles) {
  const BridgeScene sc;
  DetectParams p = isolated();
  p.merge_group_max_rel = 0.0;  // single linkage: A - C - B is one chain
  auto o = detect::measure_obstacles(sc.comp, 3, sc.disp, kCalib, p, nullptr);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_EQ(o[0].x0, 10);
  EXPECT_EQ(o[0].x1, 79);
  p.merge_group_max_rel = 0.12;  // A + C spans 7.5 %; adding B would span 15 %: refused
  p.merge_attach = true;         // and B (15 % from the group's median) does not attach
  ImageI32 labels;
  expect_bridge_joins_a_only(detect::measure_obstacles(sc.comp, 3, sc.disp, kCalib, p, &labels), labels);
  p.merge_group_max_rel = 0.16;  // a span limit above the 15 %: one chain again
  EXPECT_EQ(detect::measure_obstacles(sc.comp, 3, sc.disp, kCalib, p, nullptr).size(), 1u);
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

namespace fs {
namespace {

Obstacle box_obstacle(int id, int x0, int y0, int x1, int y1, int q4, ImageI32& labels) {
  Obstacle o;
  o.id = id, o.x0 = x0, o.y0 = y0, o.x1 = x1, o.y1 = y1, o.disparity_q4 = q4;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x)
      if (labels.at(x, y) == 0) labels.at(x, y) = id + 1, ++o.pixel_count;
  return o;
}

// The scene of the two drop tests: H (id 0), a face at Q4 320 over rows 10..49, columns 10..49; F (id 1),
// a blob at Q4 240 (25 % farther) in a hole of H over rows fy0..fy1, columns 20..35; G (id 2) at 240
// beside H (columns 60..79, rows 15..45). Sorted by id; `labels` receive id + 1.
std::vector<Obstacle> face_blob_beside(int fy0, int fy1, ImageI32& labels) {
  std::vector<Obstacle> o;
  o.push_back(box_obstacle(1, 20, fy0, 35, fy1, 240, labels));  // F first so that H's rectangle leaves its hole
  o.push_back(box_obstacle(0, 10, 10, 49, 49, 320, labels));
  o.push_back(box_obstacle(2, 60, 15, 79, 45, 240, labels));
  std::sort(o.begin(), o.end(), [](const Obstacle& a, const Obstacle& b) { return a.id < b.id; });
  return o;
}

// After a drop in that scene: F is gone (its pixel in row f_row, column 25, unlabelled), H and G stay,
// G renumbered to id 1 in the list and label 2 in the image.
void expect_only_f_dropped(const std::vector<Obstacle>& kept, const ImageI32& labels, int f_row) {
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].disparity_q4, 320);
  EXPECT_EQ(kept[1].disparity_q4, 240);
  EXPECT_EQ(kept[1].x0, 60);
  EXPECT_EQ(kept[1].id, 1);
  EXPECT_EQ(labels.at(25, f_row), 0);
  EXPECT_EQ(labels.at(70, 30), 2);
  EXPECT_EQ(labels.at(12, 12), 1);
}

TEST(DetectSeenThrough, FartherBlobInsideANearerFaceIsDropped) {
  // H: a face at Q4 320, rows 10..49, columns 10..49, with a hole (rows 20..29, columns 20..35) where the
  // matcher measured a blob F at Q4 240 (25 % farther). G at 240 beside H (columns 60..79): not enclosed.
  ImageI32 labels(100, 60, 0);
  const std::vector<Obstacle> o = face_blob_beside(20, 29, labels);
  // ids: 0 = H, 1 = F, 2 = G; labels hold id + 1.
  DetectParams p;
  p.seen_through_drop_share = 0.0;
  auto off = o;
  ImageI32 l0 = labels;
  detect::drop_seen_through(off, l0, p);
  EXPECT_EQ(off.size(), 3u);
  p.seen_through_drop_share = 0.5;
  auto on = o;
  ImageI32 l1 = labels;
  detect::drop_seen_through(on, l1, p);
  expect_only_f_dropped(on, l1, 25);
  // Within fragment merging's tolerance (F at 300 vs 320: 6.7 % < 10 %) F is not "farther": kept.
  auto near = o;
  near[1].disparity_q4 = 300;
  ImageI32 l2 = labels;
  detect::drop_seen_through(near, l2, p);
  EXPECT_EQ(near.size(), 3u);
  // F sticking out below H's face in its columns (H only above): kept.
  ImageI32 l3(100, 60, 0);
  std::vector<Obstacle> q;
  q.push_back(box_obstacle(1, 20, 40, 35, 55, 240, l3));
  q.push_back(box_obstacle(0, 10, 10, 49, 39, 320, l3));
  std::sort(q.begin(), q.end(), [](const Obstacle& a, const Obstacle& b) { return a.id < b.id; });
  detect::drop_seen_through(q, l3, p);
  EXPECT_EQ(q.size(), 2u);
}

TEST(DetectInsideNearer, FartherBlobInANearerBoxIsDropped) {
  // H (id 0): a face at Q4 320, rows 10..49, columns 10..49, with a hole where the matcher measured a blob F
  // (id 1) at Q4 240 (25 % farther): rows 35..49, columns 20..35 — reaching H's bottom edge, so H has no
  // pixels below F and the seen-through rule keeps it. G (id 2) at 240 beside H (columns 60..79).
  ImageI32 labels(100, 60, 0);
  const std::vector<Obstacle> o = face_blob_beside(35, 49, labels);
  DetectParams p;
  p.inside_drop_min_share = 0.85;
  p.inside_drop_min_ring = 0.25;
  p.inside_drop_ring_px = 6;
  p.seen_through_drop_share = 0.5;
  auto st = o;
  ImageI32 l0 = labels;
  detect::drop_seen_through(st, l0, p);
  EXPECT_EQ(st.size(), 3u);  // not enclosed above and below
  auto on = o;
  ImageI32 l1 = labels;
  detect::drop_inside_nearer(on, l1, p);
  expect_only_f_dropped(on, l1, 40);
  // Off (share 0): kept.
  auto off = o;
  ImageI32 l2 = labels;
  p.inside_drop_min_share = 0.0;
  detect::drop_inside_nearer(off, l2, p);
  EXPECT_EQ(off.size(), 3u);
  p.inside_drop_min_share = 0.85;
  // Within fragment merging's tolerance (F at 300 vs 320: 6.7 %) F is not farther: kept.
  auto near = o;
  near[1].disparity_q4 = 300;
  ImageI32 l3 = labels;
  detect::drop_inside_nearer(near, l3, p);
  EXPECT_EQ(near.size(), 3u);
  // F with more pixels than H: H is no host.
  auto big = o;
  big[1].pixel_count = big[0].pixel_count + 1;
  ImageI32 l4 = labels;
  detect::drop_inside_nearer(big, l4, p);
  EXPECT_EQ(big.size(), 3u);
}

TEST(DetectInsideNearer, FartherObstacleSeenThroughAGapOrBesideTheBoxIsKept) {
  // H (id 0, Q4 320) is two blocks joined into one box, columns 10..19 and 60..69, rows 10..49 (a box too
  // wide); F (id 1, Q4 240) stands in the gap, columns 30..49, rows 15..45: its box lies inside H's, but the
  // band of 6 px around it (columns 24..55) holds none of H's pixels — a real obstacle seen between. K (id 2,
  // Q4 240) half outside H's box (columns 62..77): box share 0.5 < 0.85.
  ImageI32 labels(100, 60, 0);
  std::vector<Obstacle> o;
  o.push_back(box_obstacle(0, 10, 10, 19, 49, 320, labels));
  {
    Obstacle right = box_obstacle(0, 60, 10, 69, 49, 320, labels);
    o[0].x1 = 69, o[0].pixel_count += right.pixel_count;
  }
  o.push_back(box_obstacle(1, 30, 15, 49, 45, 240, labels));
  ImageI32 kl = labels;
  for (int y = 20; y <= 40; ++y)
    for (int x = 70; x <= 77; ++x) kl.at(x, y) = 3;
  Obstacle k;
  k.id = 2, k.x0 = 62, k.y0 = 20, k.x1 = 77, k.y1 = 40, k.disparity_q4 = 240, k.pixel_count = 8 * 21;
  o.push_back(k);
  DetectParams p;
  p.inside_drop_min_share = 0.85;
  p.inside_drop_min_ring = 0.25;
  p.inside_drop_ring_px = 6;
  auto q = o;
  detect::drop_inside_nearer(q, kl, p);
  EXPECT_EQ(q.size(), 3u);
  // Without the band test (min_ring 0) F goes; K stays (its box is not inside enough).
  p.inside_drop_min_ring = 0.0;
  q = o;
  ImageI32 l2 = kl;
  detect::drop_inside_nearer(q, l2, p);
  ASSERT_EQ(q.size(), 2u);
  EXPECT_EQ(q[1].x0, 62);
}

TEST(DetectLinkage, SmallBridgeNoLongerJoinsObstaclesSideBySide) {
  // The bridge scene with single linkage and merge_bridge_max_px: C joins its anchor A (the closer pair,
  // 7.5 % against 8.1 %) and not B, whose median is 15 % from A's and which stands beside A.
  const BridgeScene sc;
  DetectParams p = isolated();
  p.merge_group_max_rel = 0.0;
  p.merge_bridge_max_px = 0;  // off: plain single linkage, A - C - B is one box
  ASSERT_EQ(detect::measure_obstacles(sc.comp, 3, sc.disp, kCalib, p, nullptr).size(), 1u);
  p.merge_bridge_max_px = 500;
  p.merge_bridge_max_overlap = 0.5;
  ImageI32 labels;
  expect_bridge_joins_a_only(detect::measure_obstacles(sc.comp, 3, sc.disp, kCalib, p, &labels), labels);
  p.merge_bridge_max_px = 50;  // C (66 px) is large itself: its direct pairs link as before
  EXPECT_EQ(detect::measure_obstacles(sc.comp, 3, sc.disp, kCalib, p, nullptr).size(), 1u);
}

TEST(DetectLinkage, SmallBridgeStillJoinsAPieceInTheSameColumns) {
  // D (520 px at 272, 15 % farther than A) lies below A in A's columns, 10 rows apart; a small piece C at 296
  // between them touches both. D is no neighbour beside A (it shares all its columns with A): the bridge is
  // kept, as in plain single linkage (a wrong-depth piece of A's face), unless merge_bridge_max_overlap = 1.
  ImageI32 comp(100, 100, 0);
  ImageI16 disp(100, 100, kInvalidDisp);
  fill(comp, disp, 1, 10, 10, 39, 49, 320);
  fill(comp, disp, 2, 20, 51, 25, 56, 296);
  fill(comp, disp, 3, 12, 60, 37, 79, 272);
  DetectParams p = isolated();
  p.merge_bridge_max_px = 500;
  p.merge_bridge_max_overlap = 0.5;
  auto o = detect::measure_obstacles(comp, 3, disp, kCalib, p, nullptr);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_EQ(o[0].pixel_count, 1200 + 36 + 520);
  EXPECT_EQ(o[0].y1, 79);
  p.merge_bridge_max_overlap = 1.0;  // refused for any overlap: D stays apart
  EXPECT_EQ(detect::measure_obstacles(comp, 3, disp, kCalib, p, nullptr).size(), 2u);
}

}  // namespace
}  // namespace fs
