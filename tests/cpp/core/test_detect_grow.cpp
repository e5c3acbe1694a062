// Segment extent (docs/detection.md "(e) Segment extent"): an obstacle found on part of its pixels grows over
// touching pixels whose per-segment (WTA) disparity agrees, within the margin, not over road, sky, other
// obstacles or pixels measured at another depth. Hand-made maps, so every expected box is known exactly.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

constexpr int kW = 40, kH = 30;

struct Maps {
  ImageI32 labels{kW, kH, 0};
  ImageI16 seg{kW, kH, 80};           // background superpixels at 5 px
  ImageI16 disp{kW, kH, kInvalidDisp};  // the checked map: mostly holes
  ImageU8 road{kW, kH, 0}, sky{kW, kH, 0};
  StereoCalib calib;
  Maps() {
    calib.focal_px = 100, calib.cx = 20, calib.cy = 15, calib.baseline_m = 0.1;
    // The obstacle's superpixels: d = 10 px (160 Q4) over x 10..24, rows 5..20; only x 10..14 survived the
    // LR check (labelled as obstacle 0).
    for (int y = 5; y <= 20; ++y)
      for (int x = 10; x <= 24; ++x) seg.at(x, y) = 160;
    for (int y = 5; y <= 20; ++y)
      for (int x = 10; x <= 14; ++x) labels.at(x, y) = 1, disp.at(x, y) = 160;
  }
};

Obstacle part(int id = 0) {
  Obstacle o;
  o.id = id, o.x0 = 10, o.x1 = 14, o.y0 = 5, o.y1 = 20, o.disparity_q4 = 160, o.distance_m = 1.0;
  o.pixel_count = 5 * 16;
  return o;
}

DetectParams params(double rel, double share) {
  DetectParams p;
  p.grow_rel_disparity = rel;
  p.grow_max_share = share;
  return p;
}

TEST(DetectGrow, CompletesTheObstacleOverAgreeingSegments) {
  Maps m;
  std::vector<Obstacle> obs{part()};
  detect::grow_extent(obs, m.labels, m.seg, m.disp, m.road, m.sky, m.calib, params(0.05, 2.0));
  EXPECT_EQ(obs[0].x0, 10);
  EXPECT_EQ(obs[0].x1, 24);  // the whole superpixel area, not the 5-px background beyond it
  EXPECT_EQ(obs[0].y0, 5);
  EXPECT_EQ(obs[0].y1, 20);
  EXPECT_EQ(obs[0].pixel_count, 15 * 16);
  EXPECT_EQ(m.labels.at(24, 12), 1);
  EXPECT_EQ(m.labels.at(25, 12), 0);
  EXPECT_DOUBLE_EQ(obs[0].distance_m, 1.0);                        // the distance is not re-measured
  EXPECT_DOUBLE_EQ(obs[0].lateral_m, (17.0 - 20.0) * 1.0 / 100.0);  // box centre column 17
}

TEST(DetectGrow, OffOrWithoutSegmentMapLeavesTheBox) {
  Maps m;
  std::vector<Obstacle> obs{part()};
  detect::grow_extent(obs, m.labels, m.seg, m.disp, m.road, m.sky, m.calib, params(0.0, 2.0));
  EXPECT_EQ(obs[0].x1, 14);
  detect::grow_extent(obs, m.labels, ImageI16{}, m.disp, m.road, m.sky, m.calib, params(0.05, 2.0));
  EXPECT_EQ(obs[0].x1, 14);
  EXPECT_EQ(m.labels.at(15, 12), 0);
}

TEST(DetectGrow, MarginLimitsTheGrowth) {
  Maps m;
  std::vector<Obstacle> obs{part()};
  // width 5 -> int(0.5 * 5) = 2 columns beyond each side; height 16 -> 8 rows (nothing to grow there).
  detect::grow_extent(obs, m.labels, m.seg, m.disp, m.road, m.sky, m.calib, params(0.05, 0.5));
  EXPECT_EQ(obs[0].x1, 16);
  EXPECT_EQ(obs[0].y0, 5);
  EXPECT_EQ(obs[0].y1, 20);
}

TEST(DetectGrow, StopsAtMeasuredOtherDepthRoadSkyAndDisagreeingSegments) {
  {  // a column measured at 5 px by the checked map
    Maps m;
    for (int y = 0; y < kH; ++y) m.disp.at(20, y) = 80;
    std::vector<Obstacle> obs{part()};
    detect::grow_extent(obs, m.labels, m.seg, m.disp, m.road, m.sky, m.calib, params(0.05, 2.0));
    EXPECT_EQ(obs[0].x1, 19);
  }
  {  // ... but a checked value within the tolerance (163 vs 160) does not stop it
    Maps m;
    for (int y = 0; y < kH; ++y) m.disp.at(20, y) = 163;
    std::vector<Obstacle> obs{part()};
    detect::grow_extent(obs, m.labels, m.seg, m.disp, m.road, m.sky, m.calib, params(0.05, 2.0));
    EXPECT_EQ(obs[0].x1, 24);
  }
  {  // road and sky columns
    Maps m;
    for (int y = 0; y < kH; ++y) m.road.at(18, y) = 1, m.sky.at(9, y) = 1;
    for (int y = 5; y <= 20; ++y) m.seg.at(9, y) = 160;
    std::vector<Obstacle> obs{part()};
    detect::grow_extent(obs, m.labels, m.seg, m.disp, m.road, m.sky, m.calib, params(0.05, 2.0));
    EXPECT_EQ(obs[0].x0, 10);
    EXPECT_EQ(obs[0].x1, 17);
  }
  {  // segment disparity tolerance: max(0.25 px, 5 % of 10 px) = 0.5 px = 8 Q4
    for (const auto& [v, grows] : std::vector<std::pair<int, bool>>{{168, true}, {169, false}, {152, true}, {151, false}}) {
      Maps m;
      for (int y = 5; y <= 20; ++y)
        for (int x = 15; x <= 24; ++x) m.seg.at(x, y) = std::int16_t(v);
      std::vector<Obstacle> obs{part()};
      detect::grow_extent(obs, m.labels, m.seg, m.disp, m.road, m.sky, m.calib, params(0.05, 2.0));
      EXPECT_EQ(obs[0].x1, grows ? 24 : 14) << v;
    }
  }
}

TEST(DetectGrow, NearerObstacleClaimsFirstAndOthersAreNotOverwritten) {
  Maps m;
  // A second part of the same depth at x 21..24 labelled as obstacle 1 (listed second: farther).
  for (int y = 5; y <= 20; ++y)
    for (int x = 21; x <= 24; ++x) m.labels.at(x, y) = 2, m.disp.at(x, y) = 160;
  Obstacle b = part(1);
  b.x0 = 21, b.x1 = 24;
  std::vector<Obstacle> obs{part(0), b};
  detect::grow_extent(obs, m.labels, m.seg, m.disp, m.road, m.sky, m.calib, params(0.05, 2.0));
  EXPECT_EQ(obs[0].x1, 20);  // up to the other obstacle's pixels
  EXPECT_EQ(obs[1].x0, 21);  // nothing left to grow into
  EXPECT_EQ(obs[1].x1, 24);
  EXPECT_EQ(m.labels.at(21, 12), 2);
}

}  // namespace
}  // namespace fs
