// eq. (5): gradient magnitude of the image, used by the gradient SAD of eq. (6)-(7).
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {
constexpr std::uint64_t kMaxGradient = 1443;  // largest 3x3 Sobel magnitude of 8-bit images
}  // namespace

// 3x3 Sobel gx, gy with replicated border; |grad| = sqrt(gx^2 + gy^2) rounded to nearest.
// Range 0 .. 1443 (uint16).
ImageU16 gradient_magnitude(const ImageU8& img) {
  const int w = img.width, h = img.height;
  ImageU16 out(w, h);
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* up = img.row(y > 0 ? y - 1 : 0);
    const std::uint8_t* mid = img.row(y);
    const std::uint8_t* dn = img.row(y < h - 1 ? y + 1 : h - 1);
    std::uint16_t* o = out.row(y);
    for (int x = 0; x < w; ++x) {
      const int xl = x > 0 ? x - 1 : 0, xr = x < w - 1 ? x + 1 : w - 1;
      const int gx = (up[xr] - up[xl]) + 2 * (mid[xr] - mid[xl]) + (dn[xr] - dn[xl]);
      const int gy = (dn[xl] - up[xl]) + 2 * (dn[x] - up[x]) + (dn[xr] - up[xr]);
      // v <= 2 * 1020^2: sqrt(v) is never within 1e-4 of a half-integer, and the double result is
      // accurate to 1e-12, so adding 0.5 and truncating rounds exactly (tested against isqrt).
      const int v = gx * gx + gy * gy;
      o[x] = static_cast<std::uint16_t>(std::sqrt(static_cast<double>(v)) + 0.5);
    }
  }
  return out;
}

// Not in the paper (docs/algorithm.md 2b): IGSAD (eq. 6-7) compares gradient magnitudes, which
// scale with the camera gain, while NCC and NMI do not. A gain difference between the cameras is
// removed by one global factor on the other image's gradients. Sums are exact (uint64: <= 1443 *
// 2^30 pixels); the dead band keeps small differences that come from content (the images' border
// strips, occlusions) rather than gain.
std::uint32_t compensate_gradient_gain(const ImageU16& ref, ImageU16& other, double deadband) {
  std::uint64_t sr = 0, so = 0;
  for (const std::uint16_t v : ref.data) sr += v;
  for (const std::uint16_t v : other.data) so += v;
  if (sr == 0 || so == 0) return 1u << 16;
  const double ratio = static_cast<double>(sr) / static_cast<double>(so);
  if (ratio <= 1.0 + deadband && 1.0 / ratio <= 1.0 + deadband) return 1u << 16;
  const std::uint64_t f = std::min<std::uint64_t>(((sr << 16) + so / 2) / so, std::uint64_t(1) << 20);
  for (std::uint16_t& v : other.data)
    v = static_cast<std::uint16_t>(std::min<std::uint64_t>(kMaxGradient, (v * f + (1u << 15)) >> 16));
  return static_cast<std::uint32_t>(f);
}

}  // namespace fs
