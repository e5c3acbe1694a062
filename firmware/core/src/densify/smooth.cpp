// Edge-preserving smoothing of the dense map (not in the paper; docs/algorithm.md 6d): a bilateral
// filter on the disparities themselves over a sparse grid of taps. The segment WTA paints one
// disparity per superpixel, so a slanted surface (road, wall, car side) comes out as a staircase of
// 8 px steps; averaging each pixel with the neighbours of a similar disparity (range kernel) over a
// few superpixels (space kernel) turns the staircase into the slope and leaves depth edges alone.
// Integer arithmetic only (Q4 disparities, Q12 weights): every platform gives the same map.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {

constexpr int kWeightShift = 12;  // weights Q12: 1.0 = 4096
// Range sigmas are tabled for centre values below 256 px (Q4 4096): the largest search range
// (`cost.max_disparity` <= 256) keeps every disparity below it; a larger value would use the last entry.
constexpr int kMaxDispQ4Table = 256 * kDispScale;

struct SmoothTables {
  std::vector<int> dx, dy;         // tap offsets (row-major: taps of one row are consecutive)
  int reach = 0;                   // largest |offset|
  int centre = 0;                  // index of the tap at offset (0, 0)
  std::vector<std::int32_t> ws;    // space weight per tap, Q12
  std::vector<std::uint32_t> inv;  // per centre value c (Q4): 2^16 * 128 / (2 sigma_q4(c))
};

// Range weight: Tukey's biweight (1 - (delta / 2 sigma)^2)^2, zero from 2 sigma on. Near 0 it is the
// Gaussian exp(-delta^2 / 2 sigma^2) (same curvature); unlike the Gaussian it needs no table (a
// gather that does not vectorise), only integer multiplies. k = |delta| / (2 sigma) in 1/128
// steps (rounded, through the reciprocal table), t = 1 - k^2 / 128^2 in Q12, weight t^2 in Q12.
constexpr std::uint32_t kRangeSteps = 128;

SmoothTables make_tables(const SmoothParams& p) {
  if (p.step < 1 || p.radius < 0 || p.sigma_space <= 0.0 || p.sigma_range < 0.25 || p.sigma_range_rel < 0.0)
    throw std::invalid_argument("smooth_disparity: step >= 1, radius >= 0, sigma_space > 0, sigma_range >= 0.25 px and sigma_range_rel >= 0 required");
  if (p.radius / p.step > kMaxSmoothReach)
    throw std::invalid_argument("smooth_disparity: radius / step must be <= 5 (at most 11 x 11 taps)");
  SmoothTables t;
  const int r = (p.radius / p.step) * p.step;
  t.reach = r;
  for (int oy = -r; oy <= r; oy += p.step)
    for (int ox = -r; ox <= r; ox += p.step) {
      if (ox == 0 && oy == 0) t.centre = static_cast<int>(t.dx.size());
      t.dy.push_back(oy);
      t.dx.push_back(ox);
      const double q = std::exp(-(ox * ox + oy * oy) / (2.0 * p.sigma_space * p.sigma_space));
      t.ws.push_back(static_cast<std::int32_t>(std::lround(q * (1 << kWeightShift))));
    }
  // sigma(c) = max(sigma_range, sigma_range_rel * c) [px]: a depth edge is a relative jump in disparity.
  // inv <= 2^16 * 64 / 4 = 2^20 (sigma >= 0.25 px = 4 in Q4).
  t.inv.resize(std::size_t(kMaxDispQ4Table));
  for (int c = 0; c < kMaxDispQ4Table; ++c) {
    const double sigma_q4 = std::max(p.sigma_range * kDispScale, p.sigma_range_rel * c);
    t.inv[std::size_t(c)] = static_cast<std::uint32_t>(std::lround(65536.0 * kRangeSteps / (2.0 * sigma_q4)));
  }
  return t;
}

// One tap over the columns [x0, x1) of a row: the tap's row s is read at x + dx. Branch-free
// and 32-bit throughout, so it vectorises (AVX2 / AVX-512 clones on x86-64, NEON on arm64).
// |delta| is clamped to kMaxDelta before the multiply: |delta| * inv + 2^15 <= 4095 * 2^20 + 2^15
// < 2^32 fits uint32; a Q4 map's disparities are < 256 px = 4096.
constexpr std::uint32_t kMaxDelta = 4095;

FS_TARGET_CLONES_V4
void smooth_tap(const std::int16_t* __restrict c, const std::uint32_t* __restrict invc, const std::int16_t* __restrict s,
                std::int32_t ws, std::int32_t* __restrict num, std::int32_t* __restrict den, int x0, int x1) {
  for (int x = x0; x < x1; ++x) {
    const std::int32_t v = s[x];
    const std::uint32_t diff = std::min<std::uint32_t>(static_cast<std::uint32_t>(std::abs(v - std::int32_t(c[x]))), kMaxDelta);
    const std::uint32_t k = std::min<std::uint32_t>((diff * invc[x] + (1u << 15)) >> 16, kRangeSteps);
    const std::uint32_t t = (1u << kWeightShift) - ((k * k) >> 2);  // Q12, k^2 / 4 = k^2 / 128^2 * 4096
    const std::int32_t wr = static_cast<std::int32_t>((t * t) >> kWeightShift);
    const std::int32_t wt = v == kInvalidDisp ? 0 : (ws * wr) >> kWeightShift;
    num[x] += wt * v;
    den[x] += wt;
  }
}

}  // namespace

// Bounds: weights <= 4096 * 4096 >> 12 = 4096 per tap and at most (2 kMaxSmoothReach + 1)^2 = 121
// taps: den <= 121 * 2^12 < 2^19; num = sum w * d with a valid d < 2^12 (Q4 of a disparity below
// the largest search range, 256 px) < 121 * 2^24 < 2^31: int32.
ImageI16 smooth_disparity(const ImageI16& disp, const SmoothParams& p) {
  const SmoothTables t = make_tables(p);
  const int w = disp.width, h = disp.height;
  ImageI16 out(w, h, kInvalidDisp);
  const int taps = static_cast<int>(t.dx.size());
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel
#endif
  {
    std::vector<std::int32_t> num(static_cast<std::size_t>(w)), den(static_cast<std::size_t>(w));
    std::vector<std::uint32_t> invc(static_cast<std::size_t>(w));
    std::vector<std::int16_t> padded(static_cast<std::size_t>(w + 2 * t.reach));
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(static)
#endif
    for (int y = 0; y < h; ++y) {
      const std::int16_t* c = disp.row(y);
      // The centre tap (offset 0, delta 0) weighs exactly 1.0 = 4096: summed here, skipped below.
      for (int x = 0; x < w; ++x) {
        const bool ok = c[x] != kInvalidDisp;
        num[std::size_t(x)] = ok ? std::int32_t(c[x]) << kWeightShift : 0;
        den[std::size_t(x)] = ok ? 1 << kWeightShift : 0;
      }
      for (int x = 0; x < w; ++x) invc[std::size_t(x)] = t.inv[std::size_t(std::clamp<int>(c[x], 0, kMaxDispQ4Table - 1))];
      int row_loaded = -1;
      for (int k = 0; k < taps; ++k) {
        if (k == t.centre) continue;
        const int sy = std::clamp(y + t.dy[std::size_t(k)], 0, h - 1);
        if (sy != row_loaded) {  // the tap row with its edge pixels replicated reach px each side
          const std::int16_t* src = disp.row(sy);
          std::fill(padded.begin(), padded.begin() + t.reach, src[0]);
          std::copy(src, src + w, padded.begin() + t.reach);
          std::fill(padded.begin() + t.reach + w, padded.end(), src[w - 1]);
          row_loaded = sy;
        }
        smooth_tap(c, invc.data(), padded.data() + t.reach + t.dx[std::size_t(k)], t.ws[std::size_t(k)], num.data(),
                   den.data(), 0, w);
      }
      std::int16_t* o = out.row(y);
      for (int x = 0; x < w; ++x) {
        if (c[x] == kInvalidDisp) continue;
        // dn >= the centre tap's weight (1.0 = 4096) > 0; num >= 0 (valid disparities), so the mean
        // rounded to nearest is an unsigned 32-bit division: 2 num + dn < 2^32.
        const auto dn = static_cast<std::uint32_t>(den[std::size_t(x)]);
        o[x] = static_cast<std::int16_t>((2 * static_cast<std::uint32_t>(num[std::size_t(x)]) + dn) / (2 * dn));
      }
    }
  }
  return out;
}

}  // namespace fs
