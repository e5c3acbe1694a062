// Segment extent (our addition, session 7, docs/detection.md "(e) Segment extent"). After the LR check
// and ESR the matcher leaves about half of an obstacle's pixels without a disparity (holes longer than
// the row fill), so a detected obstacle is often only part of itself (box IoU 0.2-0.5 with its ground
// truth: a miss and a false positive). The matcher also decided a disparity for every superpixel before
// the LR check (MatchResult::disp_left_wta: the per-segment WTA, Q4, constant over each segment). Here
// each obstacle grows over touching pixels whose segment disparity agrees with its median, which
// completes its extent over the superpixels the LR check invalidated, without letting those
// unchecked values create or move any obstacle (no new obstacle, distance unchanged). A pixel whose own
// (checked) disparity is valid and disagrees stops the growth: it was measured as something else.
// Because a segment's disparity is constant over the segment, growing pixel by pixel over 8-neighbours
// is the same as growing segment by segment over touching segments (within the margin).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

void grow_extent(std::vector<Obstacle>& obstacles, ImageI32& labels, const ImageI16& seg, const ImageI16& disp,
                 const ImageU8& road, const ImageU8& sky, const StereoCalib& calib, const DetectParams& p) {
  if (p.grow_rel_disparity <= 0 || seg.empty() || obstacles.empty()) return;
  const int w = labels.width, h = labels.height;
  const int min_step = int(std::lround(p.cc_min_step_px * kDispScale));
  std::vector<std::int32_t> stack;
  // Nearest first (the obstacles are sorted so): a pixel claimed by a nearer obstacle is not free for a farther one.
  for (Obstacle& o : obstacles) {
    const std::int32_t id = o.id + 1;
    const int d = o.disparity_q4;
    const int tol = std::max(min_step, int(p.grow_rel_disparity * double(d)));
    const int mx = int(p.grow_max_share * double(o.x1 - o.x0 + 1));
    const int my = int(p.grow_max_share * double(o.y1 - o.y0 + 1));
    const int gx0 = std::max(0, o.x0 - mx), gx1 = std::min(w - 1, o.x1 + mx);
    const int gy0 = std::max(0, o.y0 - my), gy1 = std::min(h - 1, o.y1 + my);
    auto free_at = [&](int x, int y) {
      const std::size_t i = std::size_t(y) * std::size_t(w) + std::size_t(x);
      if (labels.data[i] != 0 || road.data[i]) return false;
      const int q = disp.data[i];
      // Sky-coloured pixels (rule (b) by colour alone) only on their own checked disparity (grow_sky).
      if (sky.data[i]) return p.grow_sky && q >= 0 && std::abs(q - d) <= tol;
      const int s = seg.data[i];
      if (s < 0 || std::abs(s - d) > tol) return false;
      return q < 0 || std::abs(q - d) <= tol;
    };
    stack.clear();
    for (int y = o.y0; y <= o.y1; ++y)
      for (int x = o.x0; x <= o.x1; ++x)
        if (labels.at(x, y) == id) stack.push_back(y * w + x);
    int x0 = o.x0, x1 = o.x1, y0 = o.y0, y1 = o.y1, added = 0;
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      const int cx = i % w, cy = i / w;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = cx + dx, ny = cy + dy;
          if (nx < gx0 || nx > gx1 || ny < gy0 || ny > gy1 || !free_at(nx, ny)) continue;
          labels.at(nx, ny) = id;
          ++added;
          x0 = std::min(x0, nx), x1 = std::max(x1, nx), y0 = std::min(y0, ny), y1 = std::max(y1, ny);
          stack.push_back(ny * w + nx);
        }
    }
    if (added == 0) continue;
    o.x0 = x0, o.x1 = x1, o.y0 = y0, o.y1 = y1, o.pixel_count += added;
    o.lateral_m = (0.5 * (o.x0 + o.x1) - calib.cx) * o.distance_m / calib.focal_px;
  }
}

}  // namespace fs::detect

