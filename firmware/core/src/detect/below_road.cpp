// Below the road (our addition, session 7, docs/detection.md "(e) Below the road"). On a flat road, an
// object at disparity d stands where the road line reaches d; every row below that foot shows the road
// (or something nearer) in front of it, never the object itself. Pixels of an obstacle lying there are
// a measurement at the wrong depth: background disparity leaking into a nearer obstacle's plain face, or
// road noise farther than the road band. Integer: the Q4 line table and Q4 band of road_pixels.
#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

void drop_below_road(std::vector<Obstacle>& obstacles, ImageI32& labels, const std::vector<std::int32_t>& line_q4,
                     const DetectParams& p) {
  if (p.below_road_drop_share <= 0 || obstacles.empty() || line_q4.size() != std::size_t(labels.height)) return;
  const int w = labels.width, h = labels.height;
  std::vector<std::int32_t> band(std::size_t(h), 0);
  for (int v = 0; v < h; ++v) {
    const std::int32_t l = line_q4[std::size_t(v)];
    if (l != INT32_MIN)
      band[std::size_t(v)] = std::int32_t(std::lround(p.road_tolerance_px * kDispScale + p.road_tolerance_rel * std::max(0, l)));
  }
  std::vector<std::int32_t> below(obstacles.size(), 0);
  for (int y = 0; y < h; ++y) {
    const std::int32_t l = line_q4[std::size_t(y)];
    if (l == INT32_MIN) continue;
    const std::int32_t* lab = labels.row(y);
    for (int x = 0; x < w; ++x) {
      const std::int32_t id = lab[x];
      if (id <= 0 || std::size_t(id) > obstacles.size()) continue;
      below[std::size_t(id - 1)] += l - obstacles[std::size_t(id - 1)].disparity_q4 > band[std::size_t(y)];
    }
  }
  std::vector<std::int32_t> remap(obstacles.size() + 1, 0);
  std::vector<Obstacle> kept;
  for (std::size_t i = 0; i < obstacles.size(); ++i) {
    const Obstacle& o = obstacles[i];
    if (o.pixel_count > 0 && double(below[i]) >= p.below_road_drop_share * double(o.pixel_count)) continue;
    kept.push_back(o);
    kept.back().id = int(kept.size()) - 1;
    remap[std::size_t(o.id + 1)] = std::int32_t(kept.size());
  }
  if (kept.size() == obstacles.size()) return;
  for (std::int32_t& l : labels.data)
    if (l > 0 && std::size_t(l) < remap.size()) l = remap[std::size_t(l)];
  obstacles = std::move(kept);
}

}  // namespace fs::detect
