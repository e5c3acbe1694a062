// eq. (13): left-right consistency, d_l(x, y) = d_r(x - d_l(x, y), y) within max_diff.
#include <cstdlib>

#include "fuzzystereo/stages.hpp"

namespace fs {

ImageI16 left_right_check(const ImageI16& disp_left, const ImageI16& disp_right, const LrParams& p, ImageU8* mask) {
  const int w = disp_left.width, h = disp_left.height;
  ImageI16 out(w, h, kInvalidDisp);
  if (mask) *mask = ImageU8(w, h, 0);
  const int tol = p.max_diff * kDispScale;
  // Rows are independent.
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    const std::int16_t* l = disp_left.row(y);
    const std::int16_t* r = disp_right.row(y);
    std::int16_t* o = out.row(y);
    for (int x = 0; x < w; ++x) {
      const std::int16_t d = l[x];
      if (d == kInvalidDisp) continue;
      const int xr = partner_x(x, d);
      if (xr < 0 || r[xr] == kInvalidDisp) continue;
      if (std::abs(d - r[xr]) <= tol) {
        o[x] = d;
        if (mask) mask->at(x, y) = 1;
      }
    }
  }
  return out;
}

}  // namespace fs
