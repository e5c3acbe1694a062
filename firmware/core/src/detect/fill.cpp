// Hole filling before the road stage (our addition; the paper works on a dense map). Background
// interpolation along rows, as the KITTI development kit fills sparse disparity maps: a run of
// invalid pixels of at most `max_run` pixels takes the smaller (farther) of the two valid
// disparities that bound it; a run touching the right image border takes its one valid neighbour,
// a run touching the left border only when `left_border` is set: that band is what the right
// camera does not see, and its one neighbour is often a near obstacle's edge, which the fill would
// paste over the whole band. Longer runs stay invalid (no estimate is invented over a large area).
// Reason and measured effect: docs/detection.md "(0) Hole filling".
#include <algorithm>
#include <cstdint>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

ImageI16 fill_holes(const ImageI16& disp, int max_run, bool left_border) {
  ImageI16 out = disp;
  if (max_run <= 0) return out;
  const int w = disp.width;
  for (int y = 0; y < disp.height; ++y) {
    std::int16_t* r = out.row(y);
    int x = 0;
    while (x < w) {
      if (r[x] >= 0) {
        ++x;
        continue;
      }
      const int x0 = x;
      while (x < w && r[x] < 0) ++x;  // [x0, x) is an invalid run
      if (x - x0 > max_run) continue;
      const bool has_l = x0 > 0, has_r = x < w;
      if (!has_l && (!has_r || !left_border)) continue;
      std::int16_t v;
      if (has_l && has_r) v = std::min(r[x0 - 1], r[x]);
      else v = has_l ? r[x0 - 1] : r[x];
      std::fill(r + x0, r + x, v);
    }
  }
  return out;
}

}  // namespace fs::detect
