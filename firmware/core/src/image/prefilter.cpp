// Noise equalisation (not in the paper; docs/algorithm.md 2c). IGSAD (eq. 5-7) compares gradient
// magnitudes, and a Sobel magnitude turns sensor noise of std sigma into a positive bias of about
// 1.25 * sqrt(12) * sigma on every flat pixel, so when one camera is noisier than the other the
// gradients of the two views no longer agree; SLIC segments of the noisy view also get ragged.
// The matcher estimates each image's noise, and when one exceeds the other's by more than the
// configured excess it smooths both images (the same filter on both keeps them alike); pairs of
// equal noise go through bit-unchanged.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

// Immerkaer (1996) noise mask N = [1 -2 1; -2 4 -2; 1 -2 1] (it annihilates constant, linear and
// quadratic-in-one-axis intensity, so smooth shading and straight gradients give ~0). For white
// Gaussian noise of std sigma, N * I has std 6 sigma (sum of squared weights = 36). Immerkaer takes
// the mean of |N * I| over the image; edges and texture inflate that, so the median of |N * I| is
// used instead: median |X| = 0.67449 * 6 sigma for X ~ N(0, 36 sigma^2). Exact integer histogram
// of |N * I| in 0 .. 4080 over the interior pixels of every second row (y = 1, 3, 5, ...: a median
// of >= 10^5 samples on a camera frame, at half the cost). Returns sigma in grey levels (0 for
// images smaller than 3 x 3).
double estimate_noise_sigma(const ImageU8& img) {
  const int w = img.width, h = img.height;
  if (w < 3 || h < 3) return 0.0;
  constexpr std::size_t kBins = 4081;
  // Four interleaved histograms: equal neighbouring values would otherwise make every increment
  // wait for the previous one (store-to-load chain).
  std::vector<std::uint32_t> hist(4 * kBins, 0);
  std::vector<std::uint16_t> a(static_cast<std::size_t>(w));
  std::uint64_t n = 0;
  for (int y = 1; y < h - 1; y += 2) {
    const std::uint8_t* up = img.row(y - 1);
    const std::uint8_t* mid = img.row(y);
    const std::uint8_t* dn = img.row(y + 1);
    for (int x = 1; x < w - 1; ++x) {  // vectorises: no dependency between pixels
      const int v = (up[x - 1] + up[x + 1] + dn[x - 1] + dn[x + 1]) - 2 * (up[x] + dn[x] + mid[x - 1] + mid[x + 1]) +
                    4 * mid[x];
      a[std::size_t(x)] = static_cast<std::uint16_t>(v < 0 ? -v : v);
    }
    for (int x = 1; x < w - 1; ++x) ++hist[std::size_t(x & 3) * kBins + a[std::size_t(x)]];
    n += std::uint64_t(w - 2);
  }
  // Median: the smallest m with 2 * #(<= m) >= n.
  std::uint64_t c = 0;
  std::size_t m = 0;
  for (; m < kBins; ++m) {
    c += std::uint64_t(hist[m]) + hist[kBins + m] + hist[2 * kBins + m] + hist[3 * kBins + m];
    if (2 * c >= n) break;
  }
  return static_cast<double>(m) / (6.0 * 0.67449);
}

// One pass of the 3x3 binomial [1 2 1]^T [1 2 1] / 16, border replicated, rounded half up:
// out = (sum w_ij I_ij + 8) >> 4 (sum <= 16 * 255, int). Each pass divides the std of white noise
// by 16 / 6 = 2.67.
ImageU8 binomial_smooth(const ImageU8& img) {
  const int w = img.width, h = img.height;
  ImageU8 out(w, h);
  if (w == 0 || h == 0) return out;
  std::vector<std::uint16_t> col(static_cast<std::size_t>(w));  // vertical [1 2 1] sums (<= 1020)
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* up = img.row(y > 0 ? y - 1 : 0);
    const std::uint8_t* mid = img.row(y);
    const std::uint8_t* dn = img.row(y < h - 1 ? y + 1 : h - 1);
    for (int x = 0; x < w; ++x) col[std::size_t(x)] = static_cast<std::uint16_t>(up[x] + 2 * mid[x] + dn[x]);
    std::uint8_t* o = out.row(y);
    for (int x = 0; x < w; ++x) {
      const int xl = x > 0 ? x - 1 : 0, xr = x < w - 1 ? x + 1 : w - 1;
      const int s = col[std::size_t(xl)] + 2 * col[std::size_t(x)] + col[std::size_t(xr)];
      o[x] = static_cast<std::uint8_t>((s + 8) >> 4);
    }
  }
  return out;
}

// Grey-level spread: q95 - q5 of the image's grey levels (grey_quantiles); at least 1.
int grey_spread(const GreyQuantiles& q) { return std::max(1, q[18] - q[0]); }
int grey_spread(const ImageU8& img) { return grey_spread(grey_quantiles(img)); }

// How much noisier the noisier image of the pair is [grey levels of the left image]: the right
// estimate is first brought to the left's contrast (x spread_l / spread_r, so a camera gain
// difference, which scales texture and noise alike, is not taken for noise), then
// excess = sqrt(|sigma_l^2 - sigma_r'^2|) (independent noise adds in variance).
double noise_excess(double sigma_l, double sigma_r, int spread_l, int spread_r) {
  const double r = sigma_r * static_cast<double>(spread_l) / static_cast<double>(std::max(1, spread_r));
  return std::sqrt(std::fabs(sigma_l * sigma_l - r * r));
}

}  // namespace fs
