// Box extent (docs/detection.md "(e) Box extent"): ground contact on a hand-made road line table and
// on the synthetic two-box scene, where the road band removes the boxes' lowest rows; sparse side
// columns cut on a hand-made label image.
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <vector>

#include "detect_scene.hpp"
#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

// Road line d = 0.2 * (v - 50) px, 120 rows; rows <= 50 have no line value.
std::vector<std::int32_t> line_table(int rows) {
  std::vector<std::int32_t> t(std::size_t(rows), INT32_MIN);
  for (int v = 51; v < rows; ++v) t[std::size_t(v)] = std::int32_t(std::lround(16 * 0.2 * (v - 50)));
  return t;
}

Obstacle box_at(int y1, int disparity_q4) {
  Obstacle o;
  o.x0 = 10, o.x1 = 30, o.y0 = 20, o.y1 = y1, o.disparity_q4 = disparity_q4;
  return o;
}

TEST(DetectExtent, GroundContactExtendsBottomToWhereTheLineReachesTheDisparity) {
  DetectParams p;  // road band 1 px + 0.02 * line; slack 0.5 px
  p.foot_extend = true;
  p.foot_slack_px = 0.0;
  // d = 10 px (160 Q4): the line reaches 160 at row 100, so the obstacle's lowest row is 99. Row 94: line 141 (round(140.8)), band
  // round(16 + 0.02 * 141) = 19 -> 141 >= 160 - 19: a box ending at row 93 touches the band.
  std::vector<Obstacle> obs{box_at(93, 160), box_at(92, 160), box_at(100, 160), box_at(105, 160), box_at(40, 160)};
  detect::extend_to_ground(obs, line_table(120), p);
  EXPECT_EQ(obs[0].y1, 99);   // extended to the foot row
  EXPECT_EQ(obs[1].y1, 92);   // row 93: line 138 < 141: one row of road beyond the band, not touching
  EXPECT_EQ(obs[2].y1, 100);  // at or below the foot already: unchanged
  EXPECT_EQ(obs[3].y1, 105);  // reaches below the foot: never shortened
  EXPECT_EQ(obs[4].y1, 40);   // row 41 is above the horizon (no line value)
  EXPECT_EQ(obs[0].y0, 20);
  EXPECT_EQ(obs[0].x0, 10);
  EXPECT_EQ(obs[0].x1, 30);
  // The slack admits the box ending one row higher (138 >= 141 - 8).
  p.foot_slack_px = 0.5;
  obs = {box_at(92, 160)};
  detect::extend_to_ground(obs, line_table(120), p);
  EXPECT_EQ(obs[0].y1, 99);
  // Foot below the image (the line reaches d = 15 px at row 125 > 119): row 117's line 214 >= 240 -
  // 20 - 8, so the box ending at 116 touches the band and ends at the last row.
  obs = {box_at(116, 240)};
  detect::extend_to_ground(obs, line_table(120), p);
  EXPECT_EQ(obs[0].y1, 119);
  // Off: unchanged.
  p.foot_extend = false;
  obs = {box_at(93, 160)};
  detect::extend_to_ground(obs, line_table(120), p);
  EXPECT_EQ(obs[0].y1, 93);
}

TEST(DetectExtent, SceneBoxesReachTheirTrueBottomRow) {
  // 240x180, f = 200, B = 0.1, h = 0.5: box A at 2 m spans rows 90..140, box B at 4 m rows 95..115.
  // The road band takes ~6 rows of A's foot and ~5 of B's; ground contact gives them back.
  const auto s = test::make_scene(240, 180, {{40, 90, 2.0, 0.5}, {150, 200, 4.0, 0.4}}, 5, 0.25, 0.03, 200.0);
  DetectParams p;
  for (bool on : {false, true}) {
    p.foot_extend = on;
    p.foot_gap_extend = on;  // the gap rule (session 14) reaches the foot row too: both off for the short boxes
    const DetectResult r = Detector(p).detect(s.disp, s.rgb, s.calib);
    ASSERT_EQ(r.obstacles.size(), 2u);
    for (int i = 0; i < 2; ++i) {
      const int err = r.obstacles[std::size_t(i)].y1 - s.boxes[std::size_t(i)][3];
      if (on) EXPECT_LE(std::abs(err), 1) << "box " << i;
      else EXPECT_LE(err, -3) << "box " << i;  // the band's rows are missing without it
    }
  }
}

TEST(DetectExtent, SparseSideColumnsAreCut) {
  // Obstacle 0 (label 1): columns 10..29 x rows 5..34 (30 px per column), column 20 nearly empty (a
  // hole inside), and a skirt of 2 rows (33..34) at columns 30..44; obstacle 1 (label 2) elsewhere.
  ImageI32 labels(80, 40, 0);
  for (int y = 5; y <= 34; ++y)
    for (int x = 10; x <= 29; ++x) labels.at(x, y) = (x == 20 && y != 5) ? 0 : 1;
  for (int y = 33; y <= 34; ++y)
    for (int x = 30; x <= 44; ++x) labels.at(x, y) = 1;
  for (int y = 0; y <= 10; ++y)
    for (int x = 60; x <= 70; ++x) labels.at(x, y) = 2;
  const StereoCalib calib{200.0, 40.0, 20.0, 0.1, 0.5, 0.0};
  auto make = [] {
    Obstacle a, b;
    a.id = 0, a.x0 = 10, a.y0 = 5, a.x1 = 44, a.y1 = 34, a.pixel_count = 20 * 30 - 29 + 30, a.distance_m = 2.0;
    b.id = 1, b.x0 = 60, b.y0 = 0, b.x1 = 70, b.y1 = 10, b.pixel_count = 121, b.distance_m = 3.0;
    return std::vector<Obstacle>{a, b};
  };
  DetectParams p;
  p.trim_col_top_share = 0.0;  // the low-side rule alone: next test
  p.trim_col_min_share = 0.1;  // need 3 of the fullest column's 30: the 2-px skirt goes, the hole stays
  ImageI32 lab = labels;
  auto obs = make();
  detect::trim_sparse_columns(obs, lab, calib, p);
  EXPECT_EQ(obs[0].x0, 10);
  EXPECT_EQ(obs[0].x1, 29);
  EXPECT_EQ(obs[0].y0, 5);
  EXPECT_EQ(obs[0].y1, 34);
  EXPECT_EQ(obs[0].pixel_count, 20 * 30 - 29);
  EXPECT_NEAR(obs[0].lateral_m, (19.5 - 40.0) * 2.0 / 200.0, 1e-12);
  EXPECT_EQ(lab.at(35, 34), 0);  // the cut pixels leave the labels
  EXPECT_EQ(lab.at(29, 34), 1);
  EXPECT_EQ(obs[1].x0, 60);      // a full rectangle is untouched
  EXPECT_EQ(obs[1].x1, 70);
  EXPECT_EQ(lab.at(65, 5), 2);
  // A lower share keeps the skirt (2 >= 1.5); 0 = off.
  for (double share : {0.05, 0.0}) {
    p.trim_col_min_share = share;
    lab = labels;
    obs = make();
    detect::trim_sparse_columns(obs, lab, calib, p);
    EXPECT_EQ(obs[0].x1, 44) << share;
    EXPECT_EQ(lab.at(35, 34), 1) << share;
  }
}

TEST(DetectExtent, LowSideColumnsAreCutUnlessTheSkyTookTheirTop) {
  // Obstacle 0 (label 1, d = 8 px): columns 10..29 x rows 5..34, and a 10-row skirt (rows 25..34) at
  // columns 30..44 — too many pixels for the sparse rule (10 >= 0.1 * 30), but its top (row 25) lies
  // below 5 + 0.5 * 30 = 20. Obstacle 1 (label 2, d = 8 px): columns 50..69 x rows 0..29, of which
  // columns 65..69 hold only rows 20..29; their rows 0..19 are sky-masked at the obstacle's disparity
  // (the colour rule took a bright obstacle part above the horizon).
  ImageI32 labels(80, 40, 0);
  ImageU8 sky(80, 40, 0);
  ImageI16 disp(80, 40, kInvalidDisp);
  for (int y = 5; y <= 34; ++y)
    for (int x = 10; x <= 29; ++x) labels.at(x, y) = 1;
  for (int y = 25; y <= 34; ++y)
    for (int x = 30; x <= 44; ++x) labels.at(x, y) = 1;
  for (int y = 0; y <= 29; ++y)
    for (int x = 50; x <= 69; ++x) {
      if (x < 65 || y >= 20) labels.at(x, y) = 2;
      else sky.at(x, y) = 1;
      disp.at(x, y) = 128;
    }
  const StereoCalib calib{200.0, 40.0, 20.0, 0.1, 0.5, 0.0};
  auto make = [] {
    Obstacle a, b;
    a.id = 0, a.x0 = 10, a.y0 = 5, a.x1 = 44, a.y1 = 34, a.pixel_count = 750, a.disparity_q4 = 128, a.distance_m = 2.5;
    b.id = 1, b.x0 = 50, b.y0 = 0, b.x1 = 69, b.y1 = 29, b.pixel_count = 500, b.disparity_q4 = 128, b.distance_m = 2.5;
    return std::vector<Obstacle>{a, b};
  };
  DetectParams p;
  p.trim_col_min_share = 0.1;
  p.trim_col_top_share = 0.5;
  ImageI32 lab = labels;
  auto obs = make();
  detect::trim_sparse_columns(obs, lab, calib, p, &sky, &disp);
  EXPECT_EQ(obs[0].x1, 29);  // the skirt is cut
  EXPECT_EQ(obs[0].pixel_count, 600);
  EXPECT_EQ(lab.at(35, 30), 0);
  EXPECT_EQ(obs[1].x1, 69);  // the sky-masked tops at its depth count: kept
  // Without the sky mask, or with the sky pixels at another depth (10 px vs 8 px: beyond 5 %), the
  // columns 65..69 are low and go.
  lab = labels;
  obs = make();
  detect::trim_sparse_columns(obs, lab, calib, p, nullptr, nullptr);
  EXPECT_EQ(obs[1].x1, 64);
  ImageI16 disp2 = disp;
  for (int y = 0; y < 20; ++y)
    for (int x = 65; x <= 69; ++x) disp2.at(x, y) = 160;
  lab = labels;
  obs = make();
  detect::trim_sparse_columns(obs, lab, calib, p, &sky, &disp2);
  EXPECT_EQ(obs[1].x1, 64);
  // A share of 0.7 (top must be above row 26) keeps the skirt; 0 = off.
  for (double share : {0.7, 0.0}) {
    p.trim_col_top_share = share;
    lab = labels;
    obs = make();
    detect::trim_sparse_columns(obs, lab, calib, p, &sky, &disp);
    EXPECT_EQ(obs[0].x1, 44) << share;
  }
}

TEST(DetectExtent, GapToTheFootIsClosedUnlessANearerObstacleHidesIt) {
  // Road line d = 0.2 * (v - 50) px (line_table). F (id 1, d = 10 px = 160 Q4) was measured only in rows
  // 20..60 (columns 10..30): it stands where the line reaches 160 (row 100), so its foot row is 99 and the
  // gap is rows 61..99 x columns 10..30 (39 x 21 = 819 px). N (id 0, d = 15 px = 240 Q4, nearer by 50 %)
  // covers part of that gap, columns 5..35.
  const auto line = line_table(120);
  auto make = [](int n_rows) {
    ImageI32 labels(40, 120, 0);
    for (int y = 20; y <= 60; ++y)
      for (int x = 10; x <= 30; ++x) labels.at(x, y) = 2;
    for (int y = 100 - n_rows; y < 100; ++y)
      for (int x = 5; x <= 35; ++x) labels.at(x, y) = 1;
    return labels;
  };
  auto obstacles = [](int n_rows, int n_q4) {
    Obstacle n, f;
    n.id = 0, n.x0 = 5, n.x1 = 35, n.y0 = 100 - std::max(n_rows, 1), n.y1 = 99, n.disparity_q4 = n_q4;
    f.id = 1, f.x0 = 10, f.x1 = 30, f.y0 = 20, f.y1 = 60, f.disparity_q4 = 160;
    return std::vector<Obstacle>{n, f};
  };
  DetectParams p;
  p.foot_gap_extend = true;
  p.foot_gap_max_occluded = 0.3;
  // N hides 10 of the 39 gap rows (210 of 819 px, 26 % <= 30 %): F ends at its foot row.
  auto obs = obstacles(10, 240);
  detect::extend_over_gap(obs, make(10), line, p);
  EXPECT_EQ(obs[1].y1, 99);
  EXPECT_EQ(obs[1].y0, 20);
  EXPECT_EQ(obs[1].x0, 10);
  EXPECT_EQ(obs[1].x1, 30);
  // N's own foot is below the image (the line reaches 240 at row 125) and nothing nearer lies below it: it
  // ends at the last row.
  EXPECT_EQ(obs[0].y1, 119);
  // N hides 20 rows (51 %): F's lower part is behind N, the box stays.
  obs = obstacles(20, 240);
  detect::extend_over_gap(obs, make(20), line, p);
  EXPECT_EQ(obs[1].y1, 60);
  // The same 20 rows at 170 Q4 (6 % nearer, within merge_max_rel_disparity): not an occluder, F extends.
  obs = obstacles(20, 170);
  detect::extend_over_gap(obs, make(20), line, p);
  EXPECT_EQ(obs[1].y1, 99);
  // Off: unchanged.
  p.foot_gap_extend = false;
  obs = obstacles(10, 240);
  detect::extend_over_gap(obs, make(10), line, p);
  EXPECT_EQ(obs[1].y1, 60);
  // No road line (no row has a value): unchanged.
  p.foot_gap_extend = true;
  obs = obstacles(10, 240);
  detect::extend_over_gap(obs, make(10), std::vector<std::int32_t>(120, INT32_MIN), p);
  EXPECT_EQ(obs[1].y1, 60);
}

}  // namespace
}  // namespace fs
