// Connected components of the u-disparity-filtered pixels (Section III-B, after Fig. 21: the kept
// pixels become obstacle masks). The paper does not say how pixels are grouped; we use 8-connected
// components in which two neighbours join only when their Q4 disparities differ by at most
// cc_max_step_px, so two obstacles that touch in the image but stand at different depths stay apart,
// while one obstacle split over two k-means clusters joins again (docs/detection.md).
// Two-pass union-find (first pass: provisional labels from the W, NW, N, NE neighbours and unions;
// second pass: roots, renumbered in raster order of first appearance). The reference in the tests is
// a flood fill, which numbers components the same way.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

namespace {
int find(std::vector<int>& parent, int a) {
  while (parent[std::size_t(a)] != a) {
    parent[std::size_t(a)] = parent[std::size_t(parent[std::size_t(a)])];  // path halving
    a = parent[std::size_t(a)];
  }
  return a;
}
void unite(std::vector<int>& parent, int a, int b) {
  a = find(parent, a), b = find(parent, b);
  if (a == b) return;
  if (a < b) parent[std::size_t(b)] = a;  // the smaller (earlier) label is the root
  else parent[std::size_t(a)] = b;
}
}  // namespace

ImageI32 connected_components(const ImageU8& mask, const ImageI16& disp, int max_step_q4, int* count, double rel_step,
                              int min_step_q4) {
  const int w = mask.width, h = mask.height;
  ImageI32 lab(w, h, 0);
  std::vector<int> parent{0};
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* m = mask.row(y);
    const std::int16_t* d = disp.row(y);
    std::int32_t* l = lab.row(y);
    for (int x = 0; x < w; ++x) {
      if (!m[x]) continue;
      int cur = 0;
      auto consider = [&](int nx, int ny) {
        if (nx < 0 || nx >= w || ny < 0) return;
        const int nl = lab.at(nx, ny);
        if (nl == 0) return;
        const int nd = disp.at(nx, ny), step = std::abs(nd - int(d[x]));
        if (step > max_step_q4) return;
        // Relative step (docs/detection.md "(e)"): a fixed 1 px is 15 % of depth at d = 6.7 px, so
        // far neighbours 1-3 m apart joined; the step is also limited to rel_step of the larger d.
        if (rel_step > 0 && step > min_step_q4 && step > rel_step * std::max(nd, int(d[x]))) return;
        if (cur == 0) cur = nl;
        else unite(parent, cur, nl);
      };
      consider(x - 1, y);
      consider(x - 1, y - 1);
      consider(x, y - 1);
      consider(x + 1, y - 1);
      if (cur == 0) {
        cur = int(parent.size());
        parent.push_back(cur);
      }
      l[x] = cur;
    }
  }
  std::vector<int> final_label(parent.size(), 0);
  int n = 0;
  for (auto& v : lab.data) {
    if (v == 0) continue;
    const int r = find(parent, v);
    if (final_label[std::size_t(r)] == 0) final_label[std::size_t(r)] = ++n;
    v = final_label[std::size_t(r)];
  }
  if (count) *count = n;
  return lab;
}

}  // namespace fs::detect
