// Below the road (docs/detection.md "(e) Below the road"): obstacles whose pixels lie where the road at their
// own depth would be in front of them are dropped, the rest renumbered. Hand-made line table and labels.
#include <gtest/gtest.h>

#include <climits>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

constexpr int kW = 60, kH = 120;

// Road line d = 0.2 * (v - 50) px; rows <= 50 have no line value.
std::vector<std::int32_t> line_table() {
  std::vector<std::int32_t> t(std::size_t(kH), INT32_MIN);
  for (int v = 51; v < kH; ++v) t[std::size_t(v)] = std::int32_t(std::lround(16 * 0.2 * (v - 50)));
  return t;
}

// Obstacle `id` with pixels in columns x0..x0+9 over the given row ranges.
Obstacle add(ImageI32& labels, int id, int x0, int disparity_q4, std::vector<std::pair<int, int>> rows) {
  Obstacle o;
  o.id = id, o.x0 = x0, o.x1 = x0 + 9, o.disparity_q4 = disparity_q4, o.y0 = kH, o.y1 = 0;
  for (const auto& [a, b] : rows)
    for (int y = a; y <= b; ++y)
      for (int x = x0; x <= x0 + 9; ++x) labels.at(x, y) = id + 1, ++o.pixel_count;
  o.y0 = rows.front().first, o.y1 = rows.back().second;
  return o;
}

TEST(DetectBelowRoad, DropsObstaclesSeenBelowTheRoadAtTheirDepthAndRenumbers) {
  ImageI32 labels(kW, kH, 0);
  std::vector<Obstacle> obs;
  obs.push_back(add(labels, 0, 0, 160, {{80, 99}}));   // d = 10 px stands at row 99 (line 157 < 160): kept
  obs.push_back(add(labels, 1, 15, 80, {{85, 95}}));   // d = 5 px seen at rows 85-95 (line 112-144 > 80 + band 18): dropped
  obs.push_back(add(labels, 2, 30, 80, {{60, 76}}));   // d = 5 px, foot at row 75; row 76: 83 - 80 = 3 within the band: kept
  DetectParams p;
  p.below_road_drop_share = 0.5;
  detect::drop_below_road(obs, labels, line_table(), p);
  ASSERT_EQ(obs.size(), 2u);
  EXPECT_EQ(obs[0].id, 0);
  EXPECT_EQ(obs[0].disparity_q4, 160);
  EXPECT_EQ(obs[1].id, 1);
  EXPECT_EQ(obs[1].x0, 30);
  EXPECT_EQ(labels.at(35, 70), 2);  // renumbered
  EXPECT_EQ(labels.at(20, 90), 0);  // the dropped obstacle's pixels
  EXPECT_EQ(labels.at(5, 90), 1);
}

TEST(DetectBelowRoad, ShareThresholdAndOff) {
  for (const auto& [share, kept] : std::vector<std::pair<double, bool>>{{0.5, false}, {0.6, true}, {0.0, true}}) {
    ImageI32 labels(kW, kH, 0);
    // d = 5 px: 10 rows above its foot (60-69), 10 rows well below it (90-99): half its pixels below the road.
    std::vector<Obstacle> obs{add(labels, 0, 0, 80, {{60, 69}, {90, 99}})};
    DetectParams p;
    p.below_road_drop_share = share;
    detect::drop_below_road(obs, labels, line_table(), p);
    EXPECT_EQ(obs.size(), kept ? 1u : 0u) << share;
    EXPECT_EQ(labels.at(0, 95), kept ? 1 : 0) << share;
  }
}

TEST(DetectBelowRoad, NoRoadLineKeepsEverything) {
  ImageI32 labels(kW, kH, 0);
  std::vector<Obstacle> obs{add(labels, 0, 15, 80, {{85, 95}})};
  DetectParams p;
  p.below_road_drop_share = 0.5;
  detect::drop_below_road(obs, labels, std::vector<std::int32_t>(std::size_t(kH), INT32_MIN), p);
  EXPECT_EQ(obs.size(), 1u);
}

}  // namespace
}  // namespace fs
