// eq. (5): gradient magnitude of the image, used by the gradient SAD of eq. (6)-(7).
#include <array>
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {
constexpr std::uint64_t kMaxGradient = 1443;  // largest 3x3 Sobel magnitude of 8-bit images

// |grad| of one pixel from its 3x3 neighbourhood columns xl, x, xr of rows up, mid, dn.
// v = gx^2 + gy^2 <= 2 * 1020^2 < 2^24 is exact in float, and sqrtf(v) + 0.5f truncated equals the
// exact round-half-up of sqrt(v) for every such v (Gradient.FloatSqrtRoundsExactlyOverTheWholeRange
// checks both sides of every rounding step), so the float form, which vectorises twice as wide,
// gives the same integers as the double one.
inline std::uint16_t sobel_at(const std::uint8_t* up, const std::uint8_t* mid, const std::uint8_t* dn, int xl, int x, int xr) {
  const int gx = (up[xr] - up[xl]) + 2 * (mid[xr] - mid[xl]) + (dn[xr] - dn[xl]);
  const int gy = (dn[xl] - up[xl]) + 2 * (dn[x] - up[x]) + (dn[xr] - up[xr]);
  const int v = gx * gx + gy * gy;
  return static_cast<std::uint16_t>(std::sqrt(static_cast<float>(v)) + 0.5f);
}

// The interior columns 1 .. w-2 of one row: no border clamp, so the loop vectorises.
FS_TARGET_CLONES_V4
void sobel_interior(const std::uint8_t* __restrict up, const std::uint8_t* __restrict mid, const std::uint8_t* __restrict dn,
                    std::uint16_t* __restrict o, int w) {
  for (int x = 1; x < w - 1; ++x) o[x] = sobel_at(up, mid, dn, x - 1, x, x + 1);
}

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
    if (w <= 0) continue;
    o[0] = sobel_at(up, mid, dn, 0, 0, std::min(1, w - 1));  // replicated border columns
    sobel_interior(up, mid, dn, o, w);
    if (w > 1) o[w - 1] = sobel_at(up, mid, dn, w - 2, w - 1, w - 1);
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

GreyQuantiles grey_quantiles(const ImageU8& img) {
  GreyQuantiles q{};
  if (img.data.empty()) return q;
  // Four interleaved histograms: equal neighbouring grey levels would otherwise make every increment
  // wait for the previous one (store-to-load chain). uint32 counts: < 2^32 / 4 pixels each.
  std::array<std::uint32_t, 4 * 256> h4{};
  const std::size_t N = img.data.size();
  for (std::size_t i = 0; i < N; ++i) ++h4[(i & 3) * 256 + img.data[i]];
  std::array<std::uint64_t, 256> h{};
  for (std::size_t v = 0; v < 256; ++v) h[v] = std::uint64_t(h4[v]) + h4[256 + v] + h4[512 + v] + h4[768 + v];
  const std::uint64_t n = N;
  std::uint64_t c = 0;
  int v = 0;
  for (int k = 0; k < 19; ++k) {
    const std::uint64_t p = 5 * std::uint64_t(k + 1);  // percent
    while (v < 256 && 100 * (c + h[std::size_t(v)]) < p * n) c += h[std::size_t(v++)];
    q[std::size_t(k)] = std::min(v, 255);
  }
  return q;
}

// Mean absolute difference [grey levels] between the 5 %, 10 %, ..., 95 % quantiles of the grey
// levels of a and b. Two views of one scene share their grey-level distribution up to occlusions and
// view-dependent content (0.6-11.6 levels on the 27 evaluation pairs); a camera gain or tone curve
// shifts it (>= 14.2 levels under the gain, gamma and mixed distortions of `eval --radiometric`).
double grey_quantile_shift(const GreyQuantiles& qa, const GreyQuantiles& qb) {
  int sum = 0;
  for (std::size_t k = 0; k < qa.size(); ++k) sum += std::abs(qa[k] - qb[k]);
  return sum / 19.0;
}

double grey_quantile_shift(const ImageU8& a, const ImageU8& b) {
  if (a.data.empty() || b.data.empty()) return 0.0;
  return grey_quantile_shift(grey_quantiles(a), grey_quantiles(b));
}

}  // namespace fs
