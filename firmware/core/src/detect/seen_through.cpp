// Seen through a nearer obstacle (our addition, session 8, docs/detection.md "(e) Seen through"). The
// obstacles are opaque and convex (boxes, cylinders, posts, cars): where a nearer obstacle has pixels
// above and below a farther one in the same image column, the farther one would have to be seen through
// the nearer one's face. Such a farther obstacle is a measurement at the wrong depth — background disparity
// leaking into a plain face, the commonest false positive once fragments no longer chain (session 8). Per
// obstacle F and column x holding F's pixels: t(x), b(x) = its highest and lowest row there; x is enclosed
// when one nearer obstacle H (median Q4 disparity > F's * (1 + merge_max_rel_disparity): more than fragment
// merging's tolerance nearer) has a pixel in column x above t(x) and one below b(x). F is dropped when
// its enclosed columns hold >= seen_through_drop_share of its pixels for some H. Integer throughout.
#include <algorithm>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

void drop_seen_through(std::vector<Obstacle>& obstacles, ImageI32& labels, const DetectParams& p) {
  if (p.seen_through_drop_share <= 0 || obstacles.size() < 2) return;
  const int w = labels.width, h = labels.height;
  const std::size_t n = obstacles.size();
  // Per obstacle and column: highest and lowest row, pixel count.
  std::vector<std::int32_t> top(n * std::size_t(w), h), bot(n * std::size_t(w), -1), cnt(n * std::size_t(w), 0);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* lab = labels.row(y);
    for (int x = 0; x < w; ++x) {
      const std::int32_t id = lab[x];
      if (id <= 0 || std::size_t(id) > n) continue;
      const std::size_t k = std::size_t(id - 1) * std::size_t(w) + std::size_t(x);
      top[k] = std::min(top[k], y), bot[k] = std::max(bot[k], y), ++cnt[k];
    }
  }
  std::vector<bool> drop(n, false);
  for (std::size_t f = 0; f < n; ++f) {
    const Obstacle& F = obstacles[f];
    if (F.pixel_count <= 0) continue;
    for (std::size_t g = 0; g < n && !drop[f]; ++g) {
      const Obstacle& H = obstacles[g];
      if (g == f || double(H.disparity_q4) <= double(F.disparity_q4) * (1.0 + p.merge_max_rel_disparity)) continue;
      if (H.x1 < F.x0 || H.x0 > F.x1) continue;
      std::int64_t enclosed = 0;
      for (int x = std::max(F.x0, H.x0); x <= std::min(F.x1, H.x1); ++x) {
        const std::size_t kf = f * std::size_t(w) + std::size_t(x), kh = g * std::size_t(w) + std::size_t(x);
        if (cnt[kf] > 0 && cnt[kh] > 0 && top[kh] < top[kf] && bot[kh] > bot[kf]) enclosed += cnt[kf];
      }
      drop[f] = double(enclosed) >= p.seen_through_drop_share * double(F.pixel_count);
    }
  }
  std::vector<std::int32_t> remap(n + 1, 0);
  std::vector<Obstacle> kept;
  for (std::size_t i = 0; i < n; ++i) {
    if (drop[i]) continue;
    kept.push_back(obstacles[i]);
    kept.back().id = int(kept.size()) - 1;
    remap[i + 1] = std::int32_t(kept.size());
  }
  if (kept.size() == n) return;
  for (std::int32_t& l : labels.data)
    if (l > 0 && std::size_t(l) < remap.size()) l = remap[std::size_t(l)];
  obstacles = std::move(kept);
}

}  // namespace fs::detect
