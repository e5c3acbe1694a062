// Morphological closing of the road mask (paper Section III-B, Fig. 16: "morphological closing
// operation ... to remove tiny specs and smooth out the regions"). The paper does not give the
// structuring element; we use a (2r+1) x (2r+1) square because it is separable: each of the four
// passes (dilate rows, dilate columns, erode rows, erode columns) is a running count, O(1) per
// pixel whatever r. The scalar reference in tests/cpp/core/detect_reference.hpp checks the full
// 2-D window instead.
#include <algorithm>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

namespace {

// One 1-D pass over n samples at `stride`: out = any (dilate) / all (erode) within +-r.
// For erosion, samples outside [0, n) count as 1 (the border never erodes the mask).
void pass_1d(const std::uint8_t* in, std::uint8_t* out, int n, std::ptrdiff_t stride, int r, bool dilate) {
  int ones = 0;  // ones inside the clipped window [i - r, i + r]
  for (int i = 0; i < std::min(r, n); ++i) ones += in[i * stride];
  for (int i = 0; i < n; ++i) {
    const int add = i + r, sub = i - r - 1;
    if (add < n) ones += in[add * stride];
    if (sub >= 0) ones -= in[sub * stride];
    const int lo = std::max(0, i - r), hi = std::min(n - 1, i + r);
    out[i * stride] = dilate ? std::uint8_t(ones > 0) : std::uint8_t(ones == hi - lo + 1);
  }
}

void pass_2d(const ImageU8& in, ImageU8& out, int r, bool dilate) {
  ImageU8 tmp(in.width, in.height);
  for (int y = 0; y < in.height; ++y) pass_1d(in.row(y), tmp.row(y), in.width, 1, r, dilate);
  for (int x = 0; x < in.width; ++x) pass_1d(tmp.data.data() + x, out.data.data() + x, in.height, in.width, r, dilate);
}

}  // namespace

ImageU8 close_mask(const ImageU8& mask, int radius) {
  if (radius <= 0 || mask.empty()) return mask;
  ImageU8 dil(mask.width, mask.height), out(mask.width, mask.height);
  pass_2d(mask, dil, radius, true);
  pass_2d(dil, out, radius, false);
  return out;
}

}  // namespace fs::detect
