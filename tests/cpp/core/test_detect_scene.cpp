// Detection behaviour on synthetic disparity maps with known geometry: road found and removed,
// boxes recovered with their boxes and distances, speckle dropped, sky removed only in the upper
// part, mono camera skips the sky stage, config [detect] round trip.
#include <gtest/gtest.h>

#include <cmath>
#include <tuple>

#include "config.hpp"
#include "detect_config.hpp"
#include "detect_scene.hpp"
#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

// 240x180, f = 200 px, B = 0.1 m, camera 0.5 m above a flat road: road d = 0.2 * (v - 90).
// Box A: columns 40..90, Z = 2 m (d = 10 px), rows 90..140; box B: columns 150..200, Z = 4 m (d = 5 px), rows 95..115.
test::Scene two_boxes(double noise, double holes, unsigned seed = 5) {
  return test::make_scene(240, 180, {{40, 90, 2.0, 0.5}, {150, 200, 4.0, 0.4}}, seed, noise, holes, 200.0);
}

double iou(const Obstacle& o, const std::array<int, 4>& b) {
  const int ix0 = std::max(o.x0, b[0]), iy0 = std::max(o.y0, b[1]), ix1 = std::min(o.x1, b[2]), iy1 = std::min(o.y1, b[3]);
  if (ix1 < ix0 || iy1 < iy0) return 0.0;
  const double inter = double(ix1 - ix0 + 1) * (iy1 - iy0 + 1);
  const double a = double(o.x1 - o.x0 + 1) * (o.y1 - o.y0 + 1), bb = double(b[2] - b[0] + 1) * (b[3] - b[1] + 1);
  return inter / (a + bb - inter);
}

TEST(DetectScene, RoadLineAndMaskRecovered) {
  const auto s = two_boxes(0.2, 0.02);
  const DetectResult r = Detector(DetectParams{}).detect(s.disp, s.rgb, s.calib);
  ASSERT_TRUE(r.road.found);
  EXPECT_NEAR(r.road.a, 0.2, 0.02);           // B / h
  EXPECT_NEAR(-r.road.b / r.road.a, 90.0, 1.5);  // horizon at cy
  EXPECT_NEAR(r.road.horizon_row, 91, 2);
  // Road pixels (not under a box, below row 62) are in the mask; boxes mostly are not.
  int road = 0, road_hit = 0, box = 0, box_hit = 0;
  for (int y = 93; y < 180; ++y)
    for (int x = 0; x < 240; ++x) {
      bool in_box = false;
      for (const auto& b : s.boxes) in_box = in_box || (x >= b[0] && x <= b[2] && y >= b[1] && y <= b[3]);
      (in_box ? box : road)++;
      (in_box ? box_hit : road_hit) += r.road_mask.at(x, y);
    }
  EXPECT_GT(double(road_hit) / road, 0.97);
  EXPECT_LT(double(box_hit) / box, 0.30);  // only the few rows where a box meets the road
  for (int y = 0; y < 88; ++y)
    for (int x = 0; x < 240; ++x) ASSERT_EQ(r.road_mask.at(x, y), 0) << x << "," << y;
}

TEST(DetectScene, BoxesAndDistancesRecovered) {
  for (double noise : {0.0, 0.25}) {
    const auto s = two_boxes(noise, 0.03);
    const DetectResult r = Detector(DetectParams{}).detect(s.disp, s.rgb, s.calib);
    ASSERT_EQ(r.obstacles.size(), 2u) << "noise " << noise;
    const Obstacle& a = r.obstacles[0];  // nearest first
    const Obstacle& b = r.obstacles[1];
    EXPECT_NEAR(a.distance_m, 2.0, 0.1);
    EXPECT_NEAR(b.distance_m, 4.0, 0.25);
    EXPECT_GT(iou(a, s.boxes[0]), 0.6);
    EXPECT_GT(iou(b, s.boxes[1]), 0.6);
    EXPECT_EQ(a.x0, 40);
    EXPECT_EQ(a.x1, 90);
    EXPECT_EQ(a.y0, 90);
    EXPECT_EQ(a.cls, ObstacleClass::Mid);  // 2 m: near_m = 2 is exclusive
    EXPECT_EQ(b.cls, ObstacleClass::Mid);
    // Box A's centre column 65 is 55 px left of cx = 120: X = -55 * 2 / 200.
    EXPECT_NEAR(a.lateral_m, -0.55, 0.03);
    EXPECT_EQ(r.obstacle_labels.at(65, 100), 1);
    EXPECT_EQ(r.obstacle_labels.at(175, 100), 2);
    EXPECT_EQ(r.obstacle_labels.at(120, 160), 0);
    for (int i = 0; i < int(DetectStage::Count); ++i) EXPECT_GE(r.timings.ms[std::size_t(i)], 0.0);
  }
}

TEST(DetectScene, DetectorReuseGivesSameResult) {
  // The same Detector on a big frame, a small one, then the big one again: scratch reuse must not
  // leak state between frames.
  const auto big = two_boxes(0.2, 0.02, 9);
  const auto small = test::make_scene(97, 61, {{10, 30, 2.0, 0.5}}, 3, 0.2, 0.0, 80.0);
  const Detector det(DetectParams{});
  const DetectResult a = det.detect(big.disp, big.rgb, big.calib);
  (void)det.detect(small.disp, small.rgb, small.calib);
  const DetectResult b = det.detect(big.disp, big.rgb, big.calib);
  const DetectResult c = Detector(DetectParams{}).detect(big.disp, big.rgb, big.calib);
  EXPECT_EQ(a.obstacle_labels.data, b.obstacle_labels.data);
  EXPECT_EQ(a.kept.data, c.kept.data);
  ASSERT_EQ(a.obstacles.size(), b.obstacles.size());
  for (std::size_t i = 0; i < a.obstacles.size(); ++i) EXPECT_EQ(a.obstacles[i].disparity_q4, b.obstacles[i].disparity_q4);
}

TEST(DetectScene, ClassesFollowLimits) {
  DetectParams p;
  p.near_m = 3.0;
  p.far_m = 3.5;
  const auto s = two_boxes(0.0, 0.0);
  const DetectResult r = Detector(p).detect(s.disp, s.rgb, s.calib);
  ASSERT_EQ(r.obstacles.size(), 2u);
  EXPECT_EQ(r.obstacles[0].cls, ObstacleClass::Near);
  EXPECT_EQ(r.obstacles[1].cls, ObstacleClass::Far);
}

TEST(DetectScene, SpeckleRemovedByUDisparityAndArea) {
  auto s = two_boxes(0.0, 0.0);
  // Isolated 6x6 blobs (too big for a radius-2 road closing to swallow) of near disparities on the
  // road: short and low in u-disparity.
  for (int i = 0; i < 12; ++i)
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 6; ++x) s.disp.at(5 + 18 * i + x, 150 + y) = std::int16_t(16 * (20 + i));
  DetectParams base;
  base.road_close_radius = 2;  // the default 9x9 closing would already swallow the 6x6 blobs as road
  const DetectResult r = Detector(base).detect(s.disp, s.rgb, s.calib);
  EXPECT_EQ(r.obstacles.size(), 2u);
  for (int i = 0; i < 12; ++i) EXPECT_EQ(r.kept.at(7 + 18 * i, 152), 0);
  // Turning the filter off lets the blobs through to the components (they then fail min area).
  DetectParams loose = base;
  loose.udisp_min_height_px = 1;
  loose.udisp_min_run_px = 1;
  loose.min_area_px = 5;
  loose.min_area_m2 = 0.0;   // 36 px at 1 m = 0.0009 m^2: the physical-area filter would drop them too
  loose.min_height_m = 0.0;  // the blobs are 6 rows = 3 cm at 1 m: the height filter would drop them too
  loose.merge_gap_px = -1;   // and 18 px apart at 5 % disparity steps: keep them separate
  const DetectResult r2 = Detector(loose).detect(s.disp, s.rgb, s.calib);
  EXPECT_GT(r2.obstacles.size(), 2u);
}

TEST(DetectScene, SkyOnlyInUpperPart) {
  auto s = two_boxes(0.0, 0.0);
  // A sky-blue object below the horizon (a blue car) must stay.
  for (int y = 150; y < 170; ++y)
    for (int x = 100; x < 130; ++x) s.rgb.at(x, y) = Rgb8{100, 150, 230};
  const DetectResult r = Detector(DetectParams{}).detect(s.disp, s.rgb, s.calib);
  EXPECT_FALSE(r.sky_skipped);
  EXPECT_NEAR(r.sky_rows, 91, 2);  // horizon from the road line
  int upper = 0;
  for (int y = 0; y < 88; ++y)
    for (int x = 0; x < 240; ++x) upper += r.sky_mask.at(x, y);
  EXPECT_EQ(upper, 88 * 240);
  for (int y = 150; y < 170; ++y)
    for (int x = 100; x < 130; ++x) ASSERT_EQ(r.sky_mask.at(x, y), 0);
  // Fraction mode: only the top 25 %.
  DetectParams p;
  p.sky_limit = SkyLimit::Fraction;
  p.sky_upper_fraction = 0.25;
  const DetectResult r2 = Detector(p).detect(s.disp, s.rgb, s.calib);
  EXPECT_EQ(r2.sky_rows, 45);
  EXPECT_EQ(r2.sky_mask.at(10, 44), 1);
  EXPECT_EQ(r2.sky_mask.at(10, 45), 0);
  // Overcast grey and sunset orange are sky too; a saturated green is not.
  for (Rgb8 c : {Rgb8{200, 200, 205}, Rgb8{250, 140, 60}}) {
    auto s2 = s;
    for (int y = 0; y < 60; ++y)
      for (int x = 0; x < 240; ++x) s2.rgb.at(x, y) = c;
    EXPECT_EQ(Detector(DetectParams{}).detect(s2.disp, s2.rgb, s2.calib).sky_mask.at(80, 20), 1);
  }
  auto s3 = s;
  s3.rgb.at(80, 20) = Rgb8{30, 160, 40};
  EXPECT_EQ(Detector(DetectParams{}).detect(s3.disp, s3.rgb, s3.calib).sky_mask.at(80, 20), 0);
}

TEST(DetectScene, MonoCameraSkipsSky) {
  const auto s = two_boxes(0.1, 0.02);
  const DetectResult r = Detector(DetectParams{}).detect(s.disp, ImageRgb8{}, s.calib);
  EXPECT_TRUE(r.sky_skipped);
  EXPECT_EQ(r.sky_rows, 0);
  ASSERT_EQ(r.sky_mask.size(), s.disp.size());
  for (auto v : r.sky_mask.data) ASSERT_EQ(v, 0);
  EXPECT_EQ(r.obstacles.size(), 2u);
}

TEST(DetectScene, NoRoadNoObstaclesHandled) {
  // All invalid: nothing found, nothing crashes.
  ImageI16 d(64, 48, kInvalidDisp);
  StereoCalib c;
  c.focal_px = 100, c.baseline_m = 0.1, c.cx = 32, c.cy = 24;
  const DetectResult r = Detector(DetectParams{}).detect(d, ImageRgb8(64, 48), c);
  EXPECT_FALSE(r.road.found);
  EXPECT_TRUE(r.obstacles.empty());
  EXPECT_EQ(r.sky_rows, 24);  // fallback to the upper fraction
}

TEST(DetectConfig, DefaultsMatchStructAndCrossChecks) {
  const Config cfg = parse_config("", "empty");
  const DetectParams p = detect_params_from(cfg.values), d;
  EXPECT_EQ(p.kmeans_k, 6);
  EXPECT_EQ(p.kmeans_k, d.kmeans_k);
  EXPECT_EQ(p.road_close_radius, d.road_close_radius);
  EXPECT_EQ(p.udisp_min_height_px, d.udisp_min_height_px);
  EXPECT_EQ(p.udisp_min_run_px, d.udisp_min_run_px);
  EXPECT_EQ(p.min_area_px, d.min_area_px);
  EXPECT_DOUBLE_EQ(p.min_area_m2, d.min_area_m2);
  EXPECT_DOUBLE_EQ(p.road_tolerance_rel, d.road_tolerance_rel);
  EXPECT_EQ(p.road_fill_invalid_px, d.road_fill_invalid_px);
  EXPECT_DOUBLE_EQ(p.split_min_rel, d.split_min_rel);
  EXPECT_DOUBLE_EQ(p.split_max_valley, d.split_max_valley);
  EXPECT_EQ(p.split_min_px, d.split_min_px);
  EXPECT_EQ(p.split_rounds, d.split_rounds);
  EXPECT_EQ(p.merge_occluded_max_gap_px, d.merge_occluded_max_gap_px);
  EXPECT_DOUBLE_EQ(p.merge_edge_rel_disparity, d.merge_edge_rel_disparity);
  EXPECT_EQ(p.merge_edge_columns, d.merge_edge_columns);
  EXPECT_DOUBLE_EQ(p.contain_min_inside, d.contain_min_inside);
  EXPECT_DOUBLE_EQ(p.contain_merge_rel_disparity, d.contain_merge_rel_disparity);
  EXPECT_EQ(p.contain_drop_max_px, d.contain_drop_max_px);
  EXPECT_EQ(p.contain_drop_nearer_only, d.contain_drop_nearer_only);
  EXPECT_EQ(p.contain_surround, d.contain_surround);
  EXPECT_DOUBLE_EQ(p.max_distance_m, d.max_distance_m);
  EXPECT_DOUBLE_EQ(p.merge_group_max_rel, d.merge_group_max_rel);  // session 8
  EXPECT_EQ(p.merge_attach, d.merge_attach);
  EXPECT_EQ(p.merge_bridge_max_px, d.merge_bridge_max_px);  // session 10
  EXPECT_DOUBLE_EQ(p.merge_bridge_max_overlap, d.merge_bridge_max_overlap);
  EXPECT_DOUBLE_EQ(p.seen_through_drop_share, d.seen_through_drop_share);
  EXPECT_EQ(p.foot_gap_extend, d.foot_gap_extend);  // session 14
  EXPECT_DOUBLE_EQ(p.foot_gap_max_occluded, d.foot_gap_max_occluded);
  EXPECT_DOUBLE_EQ(p.inside_drop_min_share, d.inside_drop_min_share);
  EXPECT_DOUBLE_EQ(p.inside_drop_min_ring, d.inside_drop_min_ring);
  EXPECT_EQ(p.inside_drop_ring_px, d.inside_drop_ring_px);
  EXPECT_DOUBLE_EQ(p.sky_max_texture, d.sky_max_texture);
  EXPECT_EQ(p.sky_texture_radius, d.sky_texture_radius);
  EXPECT_DOUBLE_EQ(p.near_m, d.near_m);
  EXPECT_DOUBLE_EQ(p.far_m, d.far_m);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(p.sky_ranges[i].h_min, d.sky_ranges[i].h_min);
    EXPECT_EQ(p.sky_ranges[i].h_max, d.sky_ranges[i].h_max);
    EXPECT_EQ(p.sky_ranges[i].s_min, d.sky_ranges[i].s_min);
    EXPECT_EQ(p.sky_ranges[i].v_min, d.sky_ranges[i].v_min);
  }
  const DetectParams q = detect_params_from(parse_config("[detect]\nkmeans_k = 3\nsky_limit = \"fraction\"\n", "t").values);
  EXPECT_EQ(q.kmeans_k, 3);
  EXPECT_EQ(q.sky_limit, SkyLimit::Fraction);
  EXPECT_THROW(parse_config("[detect]\nkmeans_k = 17\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\nsky_limit = \"left\"\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\nsky_max_texture = -1.0\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\nmerge_group_max_rel = 1.5\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\nmerge_bridge_max_px = -1\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\nmerge_bridge_max_overlap = 1.5\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\nseen_through_drop_share = 2.0\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\nfoot_gap_max_occluded = 1.5\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\ninside_drop_min_share = -0.1\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\ninside_drop_min_ring = 1.5\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\ninside_drop_ring_px = 0\n", "t"), ConfigError);
  EXPECT_THROW(parse_config("[detect]\nsky_texture_radius = 0\n", "t"), ConfigError);
  EXPECT_THROW(detect_params_from(parse_config("[detect]\nnear_m = 9.0\nfar_m = 3.0\n", "t").values), ConfigError);
  // Cross-field rules name the file, both fields and their values.
  try {
    detect_params_from(parse_config("[detect]\nroad_slope_min = 2.5\nroad_slope_max = 0.5\n", "my.toml").values);
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(), "my.toml: fields 'detect.road_slope_min' = 2.5 and 'detect.road_slope_max' = 0.5: "
                           "road_slope_min must be <= road_slope_max");
  }
}


TEST(DetectScene, HoleFillTakesTheFartherNeighbourAndLeavesLongRuns) {
  ImageI16 d(12, 2, kInvalidDisp);
  // Row 0: 160 | 3 invalid | 96 | 6 invalid to the right border.
  d.at(0, 0) = 160, d.at(1, 0) = 160, d.at(5, 0) = 96;
  // Row 1: a run of 5 invalid between 80 and 200 (longer than max_run = 4) stays invalid.
  d.at(0, 1) = 80, d.at(6, 1) = 200;
  const ImageI16 f = detect::fill_holes(d, 4);
  for (int x = 2; x <= 4; ++x) EXPECT_EQ(f.at(x, 0), 96) << x;  // min(160, 96): the background
  for (int x = 6; x < 12; ++x) EXPECT_EQ(f.at(x, 0), kInvalidDisp) << x;  // 6 > 4
  for (int x = 1; x <= 5; ++x) EXPECT_EQ(f.at(x, 1), kInvalidDisp) << x;
  for (int x = 7; x < 12; ++x) EXPECT_EQ(f.at(x, 1), kInvalidDisp) << x;  // 5 > 4
  const ImageI16 g = detect::fill_holes(d, 6);
  for (int x = 6; x < 12; ++x) EXPECT_EQ(g.at(x, 0), 96) << x;  // border run: its one neighbour
  for (int x = 1; x <= 5; ++x) EXPECT_EQ(g.at(x, 1), 80) << x;
  EXPECT_EQ(detect::fill_holes(d, 0).data, d.data);  // 0 = off
  // A run at the left border: filled from its one neighbour only with left_border.
  ImageI16 e(8, 1, kInvalidDisp);
  e.at(3, 0) = 120, e.at(4, 0) = 40;
  const ImageI16 on = detect::fill_holes(e, 4, true), off = detect::fill_holes(e, 4, false);
  for (int x = 0; x < 3; ++x) {
    EXPECT_EQ(on.at(x, 0), 120) << x;
    EXPECT_EQ(off.at(x, 0), kInvalidDisp) << x;
  }
  for (int x = 5; x < 8; ++x) EXPECT_EQ(off.at(x, 0), 40) << x;  // the right border still fills
}

TEST(DetectScene, FragmentsMergeAndLowBoxesDrop) {
  // Two 20x30 fragments of one surface at d = 20 px (Z = 1 m at f = 200, B = 0.1), 5 px apart,
  // and a 40x4 flat strip at d = 30 px (4 rows * 0.67 m / 200 px = 1.3 cm tall).
  ImageI32 comp(100, 60, 0);
  ImageI16 disp(100, 60, kInvalidDisp);
  for (int y = 10; y < 40; ++y)
    for (int x = 0; x < 20; ++x) comp.at(10 + x, y) = 1, comp.at(35 + x, y) = 2, disp.at(10 + x, y) = 320, disp.at(35 + x, y) = 330;
  for (int y = 50; y < 54; ++y)
    for (int x = 40; x < 80; ++x) comp.at(x, y) = 3, disp.at(x, y) = 480;
  const StereoCalib calib{200.0, 50.0, 30.0, 0.1, 0.5, 0.0};
  DetectParams p;
  p.min_area_px = 10;
  p.min_area_m2 = 0.0;  // tested on its own below
  p.merge_gap_px = 8;
  p.min_height_m = 0.1;
  ImageI32 labels;
  auto o = detect::measure_obstacles(comp, 3, disp, calib, p, &labels);
  ASSERT_EQ(o.size(), 1u);  // fragments merged, the strip dropped
  EXPECT_EQ(o[0].x0, 10);
  EXPECT_EQ(o[0].x1, 54);
  EXPECT_EQ(o[0].pixel_count, 1200);
  EXPECT_EQ(labels.at(40, 20), 1);
  EXPECT_EQ(labels.at(60, 51), 0);
  p.merge_gap_px = 4;  // gap of 5 px > 4: two obstacles
  p.min_height_m = 0.0;  // and the strip stays
  EXPECT_EQ(detect::measure_obstacles(comp, 3, disp, calib, p, nullptr).size(), 3u);
  p.merge_gap_px = 8;
  p.merge_max_rel_disparity = 0.02;  // 320 vs 330 differ by 3 %: apart again ...
  p.merge_edge_rel_disparity = 0.0;  // ... unless edge continuity (3 % <= 5 %) joins the facing edges
  EXPECT_EQ(detect::measure_obstacles(comp, 3, disp, calib, p, nullptr).size(), 3u);
  p.merge_edge_rel_disparity = 0.05;
  EXPECT_EQ(detect::measure_obstacles(comp, 3, disp, calib, p, nullptr).size(), 2u);
}

TEST(DetectScene, VerticalGapJoinsAPostCutInHeight) {
  // A post (10 px wide) in two pieces at d = 20 px, rows 5-24 and 37-59 (a 12-px band without
  // disparities between them), and beside it a second post of the same depth whose pieces stand
  // side by side 12 px apart. merge_gap_vertical_px = 16 joins the stacked pieces only.
  ImageI32 comp(100, 70, 0);
  ImageI16 disp(100, 70, kInvalidDisp);
  for (int x = 10; x < 20; ++x) {
    for (int y = 5; y < 25; ++y) comp.at(x, y) = 1, disp.at(x, y) = 320;
    for (int y = 37; y < 60; ++y) comp.at(x, y) = 2, disp.at(x, y) = 320;
  }
  for (int y = 20; y < 60; ++y)
    for (int x = 0; x < 10; ++x) comp.at(50 + x, y) = 3, comp.at(72 + x, y) = 4, disp.at(50 + x, y) = 320, disp.at(72 + x, y) = 320;
  const StereoCalib calib{200.0, 50.0, 35.0, 0.1, 0.5, 0.0};
  DetectParams p;
  p.min_area_px = 10;
  p.min_area_m2 = 0.0;
  p.min_height_m = 0.0;
  p.merge_gap_px = 8;
  p.merge_edge_rel_disparity = 0.0;
  p.merge_occluded_max_gap_px = 0;
  p.merge_gap_vertical_px = 8;  // 12 px > 8 both ways: four pieces
  EXPECT_EQ(detect::measure_obstacles(comp, 4, disp, calib, p, nullptr).size(), 4u);
  p.merge_gap_vertical_px = 16;  // the stacked pieces join; the side-by-side ones stay apart
  const auto o = detect::measure_obstacles(comp, 4, disp, calib, p, nullptr);
  ASSERT_EQ(o.size(), 3u);
  int tall = 0;
  for (const auto& b : o) tall += b.x0 == 10 && b.y0 == 5 && b.y1 == 59;
  EXPECT_EQ(tall, 1);
}

TEST(DetectScene, PhysicalAreaDropsSmallSurfacesAtTheirDepth) {
  // The same 20x20 = 400-px patch at d = 20 px (Z = 1 m at f = 200 px, B = 0.1 m: 400 * (1/200)^2
  // = 0.01 m^2) and at d = 4 px (Z = 5 m: 0.25 m^2). A pixel-count limit cannot tell them apart.
  ImageI32 comp(100, 40, 0);
  ImageI16 disp(100, 40, kInvalidDisp);
  for (int y = 10; y < 30; ++y)
    for (int x = 0; x < 20; ++x) comp.at(10 + x, y) = 1, comp.at(60 + x, y) = 2, disp.at(10 + x, y) = 320, disp.at(60 + x, y) = 64;
  const StereoCalib calib{200.0, 50.0, 20.0, 0.1, 0.5, 0.0};
  DetectParams p;
  p.min_area_px = 10;
  p.min_height_m = 0.0;
  p.min_area_m2 = 0.02;
  auto o = detect::measure_obstacles(comp, 2, disp, calib, p, nullptr);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_NEAR(o[0].distance_m, 5.0, 1e-9);
  p.min_area_m2 = 0.005;
  EXPECT_EQ(detect::measure_obstacles(comp, 2, disp, calib, p, nullptr).size(), 2u);
  p.min_area_m2 = 0.0;  // off
  EXPECT_EQ(detect::measure_obstacles(comp, 2, disp, calib, p, nullptr).size(), 2u);
}

TEST(DetectScene, OccludedObstacleMergesAcrossNearerOne) {
  // One surface at d = 20 px seen left and right of a nearer one at d = 40 px: the two sides share
  // top and bottom rows and the gap is covered by the nearer box -> one obstacle. A far piece with
  // another top row, or an open gap, stays apart.
  ImageI32 comp(200, 80, 0);
  ImageI16 disp(200, 80, kInvalidDisp);
  auto fill = [&](int x0, int x1, int y0, int y1, int label, int q4) {
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) comp.at(x, y) = label, disp.at(x, y) = std::int16_t(q4);
  };
  fill(10, 39, 20, 59, 1, 320);    // left side of the far surface
  fill(40, 89, 5, 75, 2, 640);     // nearer obstacle in front
  fill(90, 119, 20, 59, 3, 322);   // right side of the far surface
  const StereoCalib calib{200.0, 100.0, 40.0, 0.1, 0.5, 0.0};
  DetectParams p;
  p.min_area_px = 10;
  p.min_area_m2 = 0.0;
  p.min_height_m = 0.0;
  p.merge_gap_px = 8;
  p.merge_occluded_max_gap_px = 200;
  ImageI32 labels;
  auto o = detect::measure_obstacles(comp, 3, disp, calib, p, &labels);
  ASSERT_EQ(o.size(), 2u);
  EXPECT_EQ(o[1].x0, 10);  // the far one, both sides
  EXPECT_EQ(o[1].x1, 119);
  EXPECT_EQ(o[1].pixel_count, 2 * 30 * 40);
  EXPECT_EQ(labels.at(15, 30), labels.at(100, 30));
  p.merge_occluded_max_gap_px = 0;  // off: three obstacles
  EXPECT_EQ(detect::measure_obstacles(comp, 3, disp, calib, p, nullptr).size(), 3u);
  p.merge_occluded_max_gap_px = 40;  // the 50-px gap is wider than allowed
  EXPECT_EQ(detect::measure_obstacles(comp, 3, disp, calib, p, nullptr).size(), 3u);
  p.merge_occluded_max_gap_px = 200;
  ImageI32 comp2 = comp;
  for (int y = 20; y < 30; ++y)
    for (int x = 90; x <= 119; ++x) comp2.at(x, y) = 0;  // right piece now starts 10 rows lower
  EXPECT_EQ(detect::measure_obstacles(comp2, 3, disp, calib, p, nullptr).size(), 3u);
  ImageI32 comp3 = comp;
  for (int y = 5; y <= 75; ++y)
    for (int x = 40; x <= 59; ++x) comp3.at(x, y) = 0;  // nearer box covers only 60..89: 20 columns open
  EXPECT_EQ(detect::measure_obstacles(comp3, 3, disp, calib, p, nullptr).size(), 3u);
}

TEST(DetectScene, EdgeContinuityJoinsASlantedSurface) {
  // As tests/python/test_detect_reference.py: a surface slanting from d = 30 px to 24 px over columns
  // 10..71, cut into two pieces 2 px apart (columns 40-41 empty, as where two k-means clusters meet):
  // medians ~28.5 / 25.5 px (11 %, beyond fragment merging) but the facing edges agree. A flat piece at
  // 30 px and one at 21 px side by side (edges 30 vs 21) stay apart.
  ImageI32 comp(200, 60, 0);
  ImageI16 disp(200, 60, kInvalidDisp);
  for (int y = 10; y < 50; ++y) {
    for (int x = 10; x < 72; ++x) {
      if (x == 40 || x == 41) continue;
      comp.at(x, y) = x < 40 ? 1 : 2;
      disp.at(x, y) = std::int16_t(std::lround(16.0 * (30.0 - 6.0 * (x - 10) / 61.0)));
    }
    for (int x = 100; x < 130; ++x) comp.at(x, y) = 3, disp.at(x, y) = 480;
    for (int x = 132; x < 160; ++x) comp.at(x, y) = 4, disp.at(x, y) = 336;
  }
  const StereoCalib calib{200.0, 100.0, 30.0, 0.1, 0.5, 0.0};
  DetectParams p;
  p.min_area_px = 10;
  p.min_area_m2 = 0.0;
  p.min_height_m = 0.0;
  p.contain_min_inside = 0.0;
  p.merge_gap_px = 8;
  p.merge_edge_rel_disparity = 0.05;
  p.merge_edge_columns = 4;
  ImageI32 labels;
  auto o = detect::measure_obstacles(comp, 4, disp, calib, p, &labels);
  ASSERT_EQ(o.size(), 3u);
  EXPECT_EQ(labels.at(20, 20), labels.at(60, 20));  // the slanted surface is one obstacle
  EXPECT_NE(labels.at(110, 20), labels.at(140, 20));
  p.merge_edge_rel_disparity = 0.0;  // off
  EXPECT_EQ(detect::measure_obstacles(comp, 4, disp, calib, p, nullptr).size(), 4u);
  p.merge_edge_rel_disparity = 0.05;
  p.merge_gap_px = 1;  // the 2-px gap is wider
  EXPECT_EQ(detect::measure_obstacles(comp, 4, disp, calib, p, nullptr).size(), 4u);
  p.merge_gap_px = 8;
  p.merge_edge_columns = 30;  // the whole pieces: 11 % apart
  EXPECT_EQ(detect::measure_obstacles(comp, 4, disp, calib, p, nullptr).size(), 4u);
}

TEST(DetectScene, ContainedGroupsJoinOrDrop) {
  // A 60x60 obstacle at d = 20 px with three smaller groups inside its box: a leftover piece at
  // d = 23 px (15 % nearer: beyond the 10 % fragment merging, within contain_merge_rel_disparity),
  // a 100-px blob at d = 40 px (matcher noise, nearer) and a 100-px blob at d = 12 px (farther).
  ImageI32 comp(120, 100, 0);
  ImageI16 disp(120, 100, kInvalidDisp);
  auto fill = [&](int x0, int x1, int y0, int y1, int label, int q4) {
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) comp.at(x, y) = label, disp.at(x, y) = std::int16_t(q4);
  };
  fill(20, 79, 20, 79, 1, 320);
  fill(30, 39, 30, 49, 2, 368);   // 200 px, 15 % nearer than the obstacle
  fill(50, 59, 30, 39, 3, 640);   // 100 px, twice as near
  fill(50, 59, 60, 69, 4, 192);   // 100 px, farther
  // The pieces overwrite the obstacle's labels: it keeps 3600 - 400 pixels of its own.
  const StereoCalib calib{200.0, 60.0, 50.0, 0.1, 0.5, 0.0};
  DetectParams p;
  p.min_area_px = 10;
  p.min_area_m2 = 0.0;
  p.min_height_m = 0.0;
  p.merge_gap_px = -1;  // no fragment merging: only the contained rule acts
  p.contain_min_inside = 0.8;
  p.contain_merge_rel_disparity = 0.2;
  p.contain_drop_max_px = 150;
  p.contain_drop_nearer_only = false;
  ImageI32 labels;
  auto o = detect::measure_obstacles(comp, 4, disp, calib, p, &labels);
  ASSERT_EQ(o.size(), 1u);  // the piece joined, both blobs dropped
  EXPECT_EQ(o[0].pixel_count, 3600 - 200);
  EXPECT_EQ(o[0].disparity_q4, 320);
  EXPECT_EQ(labels.at(35, 40), 1);  // the joined piece carries the obstacle's id
  EXPECT_EQ(labels.at(55, 35), 0);  // the dropped blob none
  p.contain_drop_nearer_only = true;  // the farther blob stays
  o = detect::measure_obstacles(comp, 4, disp, calib, p, nullptr);
  ASSERT_EQ(o.size(), 2u);
  EXPECT_EQ(o[1].disparity_q4, 192);
  p.contain_drop_nearer_only = false;
  p.contain_drop_max_px = 100;  // blobs of 100 px are not smaller than 100: kept
  EXPECT_EQ(detect::measure_obstacles(comp, 4, disp, calib, p, nullptr).size(), 3u);
  p.contain_drop_max_px = 150;
  p.contain_merge_rel_disparity = 0.1;  // the 15 % piece is now at another depth, 200 px >= 150: kept
  EXPECT_EQ(detect::measure_obstacles(comp, 4, disp, calib, p, nullptr).size(), 2u);
  p.contain_merge_rel_disparity = 0.2;
  p.contain_min_inside = 0.0;  // off: four obstacles
  EXPECT_EQ(detect::measure_obstacles(comp, 4, disp, calib, p, nullptr).size(), 4u);
  // A piece only half inside the obstacle's box is not contained.
  ImageI32 comp2 = comp;
  ImageI16 disp2 = disp;
  for (int y = 30; y <= 49; ++y)
    for (int x = 30; x <= 39; ++x) comp2.at(x, y) = 1, disp2.at(x, y) = 320;
  for (int y = 10; y <= 29; ++y)
    for (int x = 30; x <= 39; ++x) comp2.at(x, y) = 2, disp2.at(x, y) = 368;  // rows 10..29: half above the box
  p.contain_min_inside = 0.8;
  o = detect::measure_obstacles(comp2, 4, disp2, calib, p, nullptr);
  EXPECT_EQ(o.size(), 2u);  // obstacle + the half-outside piece (blobs dropped)
  // A blob in the obstacle's corner (obstacle pixels only left of and above it) is not surrounded.
  ImageI32 comp3 = comp;
  ImageI16 disp3 = disp;
  for (int y = 30; y <= 39; ++y)
    for (int x = 50; x <= 59; ++x) comp3.at(x, y) = 1, disp3.at(x, y) = 320;
  for (int y = 70; y <= 79; ++y)
    for (int x = 70; x <= 79; ++x) comp3.at(x, y) = 3, disp3.at(x, y) = 640;
  p.contain_surround = ContainSurround::Opposite;
  o = detect::measure_obstacles(comp3, 4, disp3, calib, p, nullptr);
  ASSERT_EQ(o.size(), 2u);  // obstacle + the corner blob (the farther blob 4 is still dropped)
  EXPECT_EQ(o[0].disparity_q4, 640);
  p.contain_surround = ContainSurround::Off;
  EXPECT_EQ(detect::measure_obstacles(comp3, 4, disp3, calib, p, nullptr).size(), 1u);
}

TEST(DetectScene, TwoDepthsJoinedByARampAreSplit) {
  // Two obstacles at d = 20 px and d = 14 px (30 %) touching in the image, joined into one
  // component by a 2-column ramp (as the matcher smooths a depth edge): the split separates them.
  ImageU8 m(120, 60, 0);
  ImageI16 d(120, 60, kInvalidDisp);
  for (int y = 10; y < 50; ++y)
    for (int x = 10; x < 110; ++x) {
      m.at(x, y) = 1;
      d.at(x, y) = std::int16_t(x < 59 ? 320 : x == 59 ? 290 : x == 60 ? 260 : 224);
    }
  int n = 0;
  const ImageI32 comp = detect::connected_components(m, d, 64, &n);  // ramp steps of 30-36 Q4 join
  ASSERT_EQ(n, 1);
  int ns = 0;
  const ImageI32 s = detect::split_bimodal_components(comp, n, d, 100, 0.12, 0.1, 2, &ns);
  ASSERT_EQ(ns, 2);
  EXPECT_NE(s.at(20, 20), s.at(100, 20));
  EXPECT_EQ(s.at(20, 20), s.at(58, 49));
  EXPECT_EQ(detect::split_bimodal_components(comp, n, d, 100, 0.0, 0.1, 2, &ns).data, comp.data);  // off
  EXPECT_EQ(ns, 1);
  // One slanted surface (d from 14 to 20 px linearly over 100 columns): not split.
  for (int y = 10; y < 50; ++y)
    for (int x = 10; x < 110; ++x) d.at(x, y) = std::int16_t(320 - (x - 10) * 96 / 99);
  const ImageI32 c2 = detect::connected_components(m, d, 64, &n);
  ASSERT_EQ(n, 1);
  detect::split_bimodal_components(c2, n, d, 100, 0.12, 0.1, 2, &ns);
  EXPECT_EQ(ns, 1);
}

TEST(DetectScene, TwoObstaclesJoinedAtTheirFeetAreCutAtTheNeck) {
  // Two posts (columns 10-39 and 70-99, rows 10-59) joined by a strip 6 rows high at their feet (rows
  // 54-59, columns 40-69): the strip's 30 columns hold 6 px each, under 0.3 x the posts' 50 px, so the
  // component is cut there (the strip's pixels dropped) into the two posts.
  ImageI32 comp(120, 70, 0);
  for (int y = 10; y < 60; ++y)
    for (int x = 10; x < 100; ++x)
      if (x < 40 || x >= 70 || y >= 54) comp.at(x, y) = 1;
  int n = 0;
  ImageI32 s = detect::split_necks(comp, 1, 12, 0.3, 100, 0.0, &n);
  ASSERT_EQ(n, 2);
  EXPECT_EQ(s.at(20, 30), 1);
  EXPECT_EQ(s.at(80, 30), 2);
  EXPECT_EQ(s.at(55, 57), 0);  // the neck
  EXPECT_EQ(s.at(39, 57), 1);  // the posts keep their own columns
  // The foot condition: the strip lies in the lowest 6 / 50 rows, so a foot share of 0.2 still cuts,
  // a strip at the top (rows 10-15) does not.
  EXPECT_EQ(detect::split_necks(comp, 1, 12, 0.3, 100, 0.2, &n).data, s.data);
  ImageI32 top = comp;
  for (int y = 10; y < 60; ++y)
    for (int x = 40; x < 70; ++x) top.at(x, y) = y < 16 ? 1 : 0;
  detect::split_necks(top, 1, 12, 0.3, 100, 0.2, &n);
  EXPECT_EQ(n, 1);
  detect::split_necks(top, 1, 12, 0.3, 100, 0.0, &n);  // at any height
  EXPECT_EQ(n, 2);
  // Too narrow a run (30 thin columns < 31), a run at the box side (a tail), too few pixels on one side,
  // a thick strip, or off: unchanged.
  EXPECT_EQ(detect::split_necks(comp, 1, 31, 0.3, 100, 0.0, &n).data, comp.data);
  EXPECT_EQ(n, 1);
  ImageI32 tail(120, 70, 0);
  for (int y = 10; y < 60; ++y)
    for (int x = 10; x < 100; ++x)
      if (x < 40 || y >= 54) tail.at(x, y) = 1;
  EXPECT_EQ(detect::split_necks(tail, 1, 12, 0.3, 100, 0.0, &n).data, tail.data);
  EXPECT_EQ(detect::split_necks(comp, 1, 12, 0.3, 1501, 0.0, &n).data, comp.data);  // each post: 1500 px
  EXPECT_EQ(detect::split_necks(comp, 1, 12, 0.1, 100, 0.0, &n).data, comp.data);   // 6 > 0.1 x 50
  EXPECT_EQ(detect::split_necks(comp, 1, 0, 0.3, 100, 0.0, &n).data, comp.data);
  // Other labels are left alone; labels are renumbered in raster order.
  ImageI32 two = comp;
  for (int y = 62; y < 68; ++y)
    for (int x = 0; x < 5; ++x) two.at(x, y) = 2;
  s = detect::split_necks(two, 2, 12, 0.3, 100, 0.0, &n);
  ASSERT_EQ(n, 3);
  EXPECT_EQ(s.at(2, 65), 3);
}

// Seams (session 33): one label over columns 10-69, rows 10-59 (3000 px); `paint` colours each pixel.
template <class F>
void seam_scene(ImageI32& lab, ImageRgb8& rgb, F paint) {
  lab = ImageI32(120, 70, 0);
  rgb = ImageRgb8(120, 70, Rgb8{0, 0, 0});
  for (int y = 10; y < 60; ++y)
    for (int x = 10; x < 70; ++x) {
      lab.at(x, y) = 1;
      rgb.at(x, y) = paint(x, y);
    }
}
constexpr Rgb8 kRed{200, 40, 40}, kBlue{40, 40, 200};

TEST(DetectScene, TwoTouchingObstaclesOfDifferentColourAreCutAtTheSeam) {
  ImageI32 lab;
  ImageRgb8 rgb;
  // Red columns 10-39, blue 40-69: the chromaticity step (0.516 in r and b) is largest at column 40.
  seam_scene(lab, rgb, [](int x, int) { return x < 40 ? kRed : kBlue; });
  int n = 0;
  ImageI32 s = detect::split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.7, 0.0, &n);
  ASSERT_EQ(n, 2);
  EXPECT_EQ(s.at(39, 30), 1);
  EXPECT_EQ(s.at(40, 30), 2);
  EXPECT_EQ(s.at(10, 59), 1);
  EXPECT_EQ(s.at(69, 10), 2);
  // Off, a threshold above the step, too few pixels or columns on a side, or no colour: unchanged.
  for (const auto& [step, width, px] : {std::tuple{0.0, 14, 300}, {0.6, 14, 300}, {0.08, 31, 300}, {0.08, 14, 1501}}) {
    EXPECT_EQ(detect::split_seams(lab, 1, rgb, step, 8, width, px, 2, 0.7, 0.0, &n).data, lab.data) << step;
    EXPECT_EQ(n, 1);
  }
  EXPECT_EQ(detect::split_seams(lab, 1, ImageRgb8(), 0.08, 8, 14, 300, 2, 0.7, 0.0, &n).data, lab.data);
  // A sliver: red columns 10-23 (700 px, 23 % of the label) are cut off, and dropped with drop_share 0.25.
  seam_scene(lab, rgb, [](int x, int) { return x < 24 ? kRed : kBlue; });
  s = detect::split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.7, 0.0, &n);
  EXPECT_EQ(n, 2);
  EXPECT_EQ(s.at(23, 30), 1);
  s = detect::split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.7, 0.25, &n);
  ASSERT_EQ(n, 1);
  EXPECT_EQ(s.at(23, 30), 0);
  EXPECT_EQ(s.at(24, 30), 1);
}

TEST(DetectScene, ColourBlobsOfOneSurfaceAreNotASeam) {
  // Camouflage-like: rows 10-34 red in columns 10-49, rows 35-59 red in columns 10-29, blue elsewhere.
  // The column means step at columns 30 and 50 (0.258 each), but only half the rows change colour there.
  ImageI32 lab;
  ImageRgb8 rgb;
  seam_scene(lab, rgb, [](int x, int y) { return x < (y < 35 ? 50 : 30) ? kRed : kBlue; });
  int n = 0;
  EXPECT_EQ(detect::split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.7, 0.0, &n).data, lab.data);
  EXPECT_EQ(n, 1);
  // Without the row test the two steps are cut, the left one first (a tie), then the right one.
  const ImageI32 s = detect::split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.0, 0.0, &n);
  ASSERT_EQ(n, 3);
  EXPECT_EQ(s.at(29, 12), 1);
  EXPECT_EQ(s.at(30, 12), 2);
  EXPECT_EQ(s.at(49, 12), 2);
  EXPECT_EQ(s.at(50, 12), 3);
  EXPECT_EQ(detect::split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 1, 0.0, 0.0, &n).at(50, 12), 2);  // one cut only
}

// Side faces (session 33): H = columns 10-49, rows 10-59 at 20 px (2000 px); F = a strip beside it.
TEST(DetectScene, TheSideFaceOfABoxJoinsItsFrontFace) {
  auto run = [](int fx0, int fx1, int f_px, int& n_out, ImageI32* labels_out = nullptr) {
    ImageI32 labels(80, 70, 0);
    for (int y = 10; y < 60; ++y)
      for (int x = 10; x < 50; ++x) labels.at(x, y) = 1;
    for (int y = 12; y < 59; ++y)
      for (int x = fx0; x <= fx1; ++x)
        if (labels.at(x, y) == 0) labels.at(x, y) = 2;
    std::vector<Obstacle> obs(2);
    obs[0] = {0, 10, 10, 49, 59, 2000, 20 * kDispScale, 2.0, 0.0, ObstacleClass::Mid};
    obs[1] = {1, fx0, 12, fx1, 58, 300, f_px, 2.5, 0.0, ObstacleClass::Mid};
    DetectParams p;
    p.side_face_max_rel = 0.35;
    p.side_face_max_width = 0.2;
    p.side_face_min_rows = 0.8;
    p.side_face_max_gap_px = 2;
    detect::merge_side_faces(obs, labels, p);
    n_out = int(obs.size());
    if (labels_out) *labels_out = labels;
    return obs;
  };
  int n = 0;
  ImageI32 lab;
  // 16 px: 1.25x farther, 6 columns (0.15 of 40), overlapping one column, centre outside H: joins.
  std::vector<Obstacle> o = run(49, 54, 16 * kDispScale, n, &lab);
  ASSERT_EQ(n, 1);
  EXPECT_EQ(o[0].x1, 54);
  EXPECT_EQ(o[0].x0, 10);
  EXPECT_EQ(o[0].pixel_count, 2300);
  EXPECT_EQ(o[0].disparity_q4, 20 * kDispScale);  // the nearer face's distance
  EXPECT_EQ(lab.at(52, 30), 1);
  run(51, 56, 16 * kDispScale, n);  // one column apart (gap 1 <= 2): joins
  EXPECT_EQ(n, 1);
  // Too far behind (20 / 14 = 1.43x), nearer (22 px), too wide (9 columns > 8), too far apart (gap 3): kept apart.
  run(49, 54, 14 * kDispScale, n);
  EXPECT_EQ(n, 2);
  run(49, 54, 22 * kDispScale, n);
  EXPECT_EQ(n, 2);
  run(49, 57, 16 * kDispScale, n);
  EXPECT_EQ(n, 2);
  run(53, 58, 16 * kDispScale, n);
  EXPECT_EQ(n, 2);
  // Off: unchanged.
  ImageI32 labels(80, 70, 0);
  std::vector<Obstacle> two(2);
  two[0] = {0, 10, 10, 49, 59, 2000, 20 * kDispScale, 2.0, 0.0, ObstacleClass::Mid};
  two[1] = {1, 49, 12, 54, 58, 300, 16 * kDispScale, 2.5, 0.0, ObstacleClass::Mid};
  DetectParams off;
  off.side_face_max_rel = 0.0;
  detect::merge_side_faces(two, labels, off);
  EXPECT_EQ(two.size(), 2u);
}

}  // namespace
}  // namespace fs
