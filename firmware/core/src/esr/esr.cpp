// Entropy-based selective refinement (ESR), Section III-A, eq. (14)-(15).
//
// Block entropy, eq. (14): histogram of the integer disparities of the valid pixels in the w x w
// block (clipped at the image border), H = log2(n) - (1/n) sum_c c log2 c [bit, Q16].
// Sliding window: the block histogram moves along the row; each pixel entering or leaving changes
// one bin c -> c +- 1 and the running sum by T[c +- 1] - T[c] (n*log2 n table), so a pixel costs
// O(1) and an output pixel O(w) (one column in, one column out) instead of O(w^2) plus a pass over
// all D bins for a recomputation. Vertical runs of equal bin (the maps are piecewise constant per
// segment; run lengths are precomputed once per map) enter and leave as one step c -> c +- k,
// which telescopes to the same integer sum as k single steps, so in practice an output pixel
// costs a few table reads; where the column entering the block equals the one leaving it, the
// entropy is carried over without any. Rows are independent and run in parallel.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {
// recip[k] = ceil(2^32 / k) for k = 1 .. kmax (recip[0] unused): floor(a * recip[k] / 2^32) = floor(a / k)
// exactly for every dividend with a * k < 2^32 (the error term a * (recip[k] - 2^32 / k) / 2^32 < a / 2^32
// < 1 / k cannot carry past the next multiple of 1 / k).
std::vector<std::uint64_t> ceil_reciprocals_2p32(std::uint64_t kmax) {
  std::vector<std::uint64_t> recip(std::size_t(kmax) + 1, 0);
  for (std::uint64_t k = 1; k <= kmax; ++k) recip[std::size_t(k)] = ((std::uint64_t(1) << 32) + k - 1) / k;
  return recip;
}

// Per-row passes of block_entropy's precomputation, one call per row (clone dispatch per row, loops
// branch-free so they vectorise).
FS_TARGET_CLONES_V4
void bins_row(const std::int16_t* __restrict d, std::int16_t* __restrict b, int w, std::int16_t dmax) {
  for (int x = 0; x < w; ++x) {
    const auto v = static_cast<std::int16_t>((d[x] + kDispScale / 2) >> kDispShift);
    b[x] = d[x] == kInvalidDisp ? std::int16_t(-1) : std::min(v, dmax);
  }
}

// rl[x] = min(below[x] + 1, cap) where b[x] == b1[x] (the run continues downwards), else 1.
FS_TARGET_CLONES_V4
void run_row(const std::int16_t* __restrict b, const std::int16_t* __restrict b1, const std::int16_t* __restrict below,
             std::int16_t* __restrict rl, int w, std::int16_t cap) {
  for (int x = 0; x < w; ++x) {
    const auto next = static_cast<std::int16_t>(std::min<std::int16_t>(static_cast<std::int16_t>(below[x] + 1), cap));
    rl[x] = b[x] == b1[x] ? next : std::int16_t(1);
  }
}

// s[x] = min(below[x] + 1, cap) (below = nullptr: the last row, 1) where b[x] == b[x - window], else 0,
// for x in [window, w).
FS_TARGET_CLONES_V4
void same_row(const std::int16_t* __restrict b, const std::int16_t* __restrict below, std::int16_t* __restrict s, int w,
              int window, std::int16_t cap) {
  if (below == nullptr) {
    for (int x = window; x < w; ++x) s[x] = b[x] == b[x - window] ? std::int16_t(1) : std::int16_t(0);
    return;
  }
  for (int x = window; x < w; ++x) {
    const auto next = static_cast<std::int16_t>(std::min<std::int16_t>(static_cast<std::int16_t>(below[x] + 1), cap));
    s[x] = b[x] == b[x - window] ? next : std::int16_t(0);
  }
}
}  // namespace

ImageI32 block_entropy(const ImageI16& disp, int window, int max_disparity, const ImageU8* need) {
  const int w = disp.width, h = disp.height, r = window / 2;
  const std::vector<std::uint64_t> T = detail::nlogn_table_q16(std::size_t(window) * std::size_t(window));
  // Once per map: the histogram bin of every pixel (nearest integer px, -1 if invalid) and the
  // length of the vertical run of equal bins starting there, downwards (capped at the window).
  // A column of a block is then entered or left in one table step per run.
  ImageI16 bins(w, h);
  ImageI16 run(w, h);
  const auto dmax = static_cast<std::int16_t>(max_disparity);
  const auto wcap = static_cast<std::int16_t>(window);
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) bins_row(disp.row(y), bins.row(y), w, dmax);
  // Branch-free and restrict-qualified so the compiler vectorises it (a row depends on the one
  // below it, the columns of a row do not).
  std::fill(run.row(h - 1), run.row(h - 1) + w, std::int16_t(1));
  for (int y = h - 2; y >= 0; --y) run_row(bins.row(y), bins.row(y + 1), run.row(y + 1), run.row(y), w, wcap);
  // Once per map as well: same(x, y) = the vertical run, downwards, over which the column at x
  // equals the column at x - window bin for bin (capped at the window). When the column entering
  // a block (x + r) equals the one leaving it (x - r - 1) over all the block's rows, the
  // histogram, and so the entropy, does not change: common inside segments wider than the window.
  ImageI16 same(w, h, 0);
  for (int y = h - 1; y >= 0; --y) same_row(bins.row(y), y + 1 < h ? same.row(y + 1) : nullptr, same.row(y), w, window, wcap);
  ImageI32 out(w, h, 0);
  // eq. (14)'s division by n <= w^2 as a multiplication by recip[n] = ceil(2^32 / n): for a
  // dividend q < 2^32 / n, floor(q * recip[n] / 2^32) = floor(q / n) exactly (the error term
  // q * (recip[n] - 2^32 / n) / 2^32 < q / 2^32 < 1 / n cannot carry past the next multiple of
  // 1 / n). The dividend is at most T[n] + n / 2, so this holds when (T[w^2] + w^2) * w^2 < 2^32,
  // i.e. windows up to 9; larger windows divide.
  const std::uint64_t nmax = T.size() - 1;
  const bool reciprocal = (T.back() + nmax) * nmax < (std::uint64_t(1) << 32);
  const std::vector<std::uint64_t> recip = ceil_reciprocals_2p32(nmax);
  const bool small_table = T.back() + T.size() < (std::uint64_t(1) << 32);
  const std::uint64_t* __restrict Tp = T.data();
  const std::uint64_t* __restrict Rp = recip.data();
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    const int y0 = std::max(0, y - r), y1 = std::min(h - 1, y + r), nr = y1 - y0 + 1;
    // Bins 0 .. max_disparity, and one more that invalid pixels address with a count of 0 (it
    // stays 0: no branch on validity in add_col).
    std::vector<std::uint32_t> hist_v(std::size_t(max_disparity) + 2, 0);
    const auto dummy = static_cast<std::int16_t>(max_disparity + 1);
    std::uint32_t* __restrict hist = hist_v.data();
    const std::int16_t* __restrict bcol = bins.row(y0);  // column x of the block: bcol[x + k*w]
    const std::int16_t* __restrict rcol = run.row(y0);
    const std::int16_t* __restrict srow = same.row(y0);
    std::int32_t* __restrict o = out.row(y);
    std::uint64_t n = 0, sum_t = 0;
    // Adds (sign +1) or removes (-1) one column of the block, one vertical run at a time:
    // c -> c +- k in one table step.
    auto add_col = [&](int x, int sign) {
      int k0 = 0;
      while (k0 < nr) {
        const std::size_t at = std::size_t(k0) * std::size_t(w) + std::size_t(x);
        const std::int16_t b0 = bcol[at];
        const int k = std::min<int>(rcol[at], nr - k0);
        k0 += k;
        const std::int16_t b = b0 < 0 ? dummy : b0;
        std::uint32_t& c = hist[std::size_t(b)];
        const auto uk = b0 < 0 ? 0u : static_cast<std::uint32_t>(k);
        if (sign > 0) { sum_t += Tp[c + uk] - Tp[c]; c += uk; n += uk; }
        else          { sum_t -= Tp[c] - Tp[c - uk]; c -= uk; n -= uk; }
      }
    };
    // eq. (14)'s quotient of the block in hist: detail::entropy_q16's integer quotient, by the
    // reciprocal (windows <= 9), a 32-bit division when the table fits (w <= 33: T[w^2] < 2^32) or
    // the 64-bit one.
    auto entropy = [&]() -> std::int32_t {
      if (reciprocal) {
        const std::uint64_t tn = Tp[n];
        return n == 0 || tn <= sum_t ? 0 : static_cast<std::int32_t>(((tn - sum_t + n / 2) * Rp[n]) >> 32);
      }
      if (small_table) {
        const auto n32 = static_cast<std::uint32_t>(n);
        const auto tn = static_cast<std::uint32_t>(Tp[n]), st = static_cast<std::uint32_t>(sum_t);
        return n32 == 0 || tn <= st ? 0 : static_cast<std::int32_t>((tn - st + n32 / 2) / n32);
      }
      return static_cast<std::int32_t>(detail::entropy_q16(T, n, sum_t));
    };
    // The block centred on column `cur` is in hist (cur = -1: none yet); e is its entropy when
    // have_e. Moving the centre one column right: where the same column leaves and enters, the
    // histogram, and so e, stays as it is.
    const std::uint8_t* need_row = need ? need->row(y) : nullptr;
    int cur = -1;
    bool have_e = false;
    std::int32_t e = 0;
    auto step_right = [&] {
      const int x = cur + 1;
      const bool leave = x - r - 1 >= 0, enter = x + r < w;
      cur = x;
      if (leave && enter && srow[x + r] >= nr) return;  // the same column leaves and enters
      if (leave) add_col(x - r - 1, -1);  // leave first: counts never exceed w*w (table size)
      if (enter) add_col(x + r, +1);
      have_e = false;
    };
    for (int x = 0; x < w; ++x) {
      if (need_row && need_row[x] == 0) continue;  // not needed: left as 0
      if (cur >= 0 && x - cur > window) {
        // A gap wider than the window: emptying the block and building the new one (2w column
        // steps) is cheaper than sliding across (2 steps per column).
        for (int c = std::max(0, cur - r); c <= std::min(w - 1, cur + r); ++c) add_col(c, -1);
        cur = -1;
      }
      if (cur < 0) {  // n = sum_t = 0 and every bin 0 here
        for (int c = std::max(0, x - r); c <= std::min(w - 1, x + r); ++c) add_col(c, +1);
        cur = x;
        have_e = false;
      }
      while (cur < x) step_right();
      if (!have_e) {
        e = entropy();
        have_e = true;
      }
      o[x] = e;
    }
  }
  return out;
}

// Mean of the valid disparities (Q4) in the clipped w x w block, rounded to nearest; kInvalidDisp
// when the block has no valid pixel. Separable running sums: per output row, the column sums of
// the block's rows (sum, count), then a window sliding along the row. int32 is exact: a block holds
// at most w^2 <= 99^2 values <= 32767 (< 2^29).
ImageI16 block_mean(const ImageI16& disp, int window) {
  const int w = disp.width, h = disp.height, r = window / 2;
  ImageI16 out(w, h, kInvalidDisp);
  // The rounded mean (2 s + n) / (2 n) by a multiplication (ceil_reciprocals_2p32): exact while a * k < 2^32;
  // here a <= 2 n * 32767 + n and k = 2 n, so a * k <= 131070 n^2 < 2^32 for n <= 181, i.e. windows up to 13;
  // larger windows divide.
  const std::int64_t nmax = std::int64_t(window) * window;
  const bool reciprocal = 131070 * nmax * nmax < (std::int64_t(1) << 32);
  const std::vector<std::uint64_t> recip = ceil_reciprocals_2p32(reciprocal ? std::uint64_t(2 * nmax) : 0);
  const std::uint64_t* const rp = recip.data();
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel
#endif
  {
    std::vector<std::int32_t> cs(std::size_t(w), 0), cn(std::size_t(w), 0);
    int have0 = 0, have1 = -1;  // rows [have0, have1] are in the column sums
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(static)
#endif
    for (int y = 0; y < h; ++y) {
      const int y0 = std::max(0, y - r), y1 = std::min(h - 1, y + r);
      if (y0 > have1 || y1 < have0 || y0 < have0) {  // first row of this thread's chunk: rebuild
        std::fill(cs.begin(), cs.end(), 0);
        std::fill(cn.begin(), cn.end(), 0);
        have0 = y0;
        have1 = y0 - 1;
      }
      for (; have0 < y0; ++have0) {  // rows leaving the block
        const std::int16_t* d = disp.row(have0);
        for (int x = 0; x < w; ++x) {
          const std::int32_t v = d[x], ok = v != kInvalidDisp;
          cs[std::size_t(x)] -= ok ? v : 0;
          cn[std::size_t(x)] -= ok;
        }
      }
      for (; have1 < y1; ) {  // rows entering the block
        const std::int16_t* d = disp.row(++have1);
        for (int x = 0; x < w; ++x) {
          const std::int32_t v = d[x], ok = v != kInvalidDisp;
          cs[std::size_t(x)] += ok ? v : 0;
          cn[std::size_t(x)] += ok;
        }
      }
      std::int32_t s = 0, n = 0;
      for (int x = 0; x <= std::min(w - 1, r - 1); ++x) { s += cs[std::size_t(x)]; n += cn[std::size_t(x)]; }
      std::int16_t* o = out.row(y);
      for (int x = 0; x < w; ++x) {
        if (x + r < w) { s += cs[std::size_t(x + r)]; n += cn[std::size_t(x + r)]; }
        if (x - r - 1 >= 0) { s -= cs[std::size_t(x - r - 1)]; n -= cn[std::size_t(x - r - 1)]; }
        if (n > 0)
          o[x] = static_cast<std::int16_t>(reciprocal ? (std::uint64_t(2 * s + n) * rp[2 * n]) >> 32 : (2 * s + n) / (2 * n));
      }
    }
  }
  return out;
}

ImageI16 entropy_selective_refinement(const ImageI16& disp_lr, const ImageI16& disp_right, const EsrParams& p,
                                      int max_disparity, ImageU8* replaced) {
  const int w = disp_lr.width, h = disp_lr.height;
  // Left and right block entropies and means are independent (0 = the thread count set by the
  // matcher). The means are whole images (separable running sums, a few operations a pixel): on
  // KITTI eq. (15) replaces ~20 % of the pixels, and a per-pixel w x w sum there cost more
  // (session 11, six interleaved bench runs: ESR / segmentation time 0.565 -> 0.500 at 1 thread,
  // 0.582 -> 0.518 at 2; docs/results.md "Speed, session 11").
  //
  // eq. (15) reads E_l only at valid left pixels whose partner x - d lies in the image, and E_r
  // only at those partners (~50 % of either map on KITTI): the entropies are computed there alone
  // (block_entropy's `need` masks), the rest of each entropy image is 0 and never read.
  ImageU8 need_l(w, h, 0), need_r(w, h, 0);
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    const std::int16_t* d = disp_lr.row(y);
    std::uint8_t* nl = need_l.row(y);
    std::uint8_t* nr = need_r.row(y);
    for (int x = 0; x < w; ++x) {
      if (d[x] == kInvalidDisp) continue;
      const int xr = partner_x(x, d[x]);
      if (xr < 0 || xr >= w) continue;
      nl[x] = 1;
      nr[xr] = 1;
    }
  }
  ImageI32 El, Er;
  ImageI16 Ml, Mr;
  detail::run_pair(
      0, [&] { El = block_entropy(disp_lr, p.window, max_disparity, &need_l); Ml = block_mean(disp_lr, p.window); },
      [&] { Er = block_entropy(disp_right, p.window, max_disparity, &need_r); Mr = block_mean(disp_right, p.window); });
  const auto tau = static_cast<std::int64_t>(std::llround(p.tau * kQ16One));
  ImageI16 out = disp_lr;
  if (replaced) *replaced = ImageU8(w, h, 0);
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (need_l.at(x, y) == 0) continue;  // invalid, or its partner outside the image
      const int xr = partner_x(x, disp_lr.at(x, y));
      const std::int64_t el = El.at(x, y), er = Er.at(xr, y);
      if (std::llabs(el - er) <= tau) continue;  // eq. (15), "otherwise"
      const std::int16_t m = el < er ? Ml.at(x, y) : Mr.at(xr, y);
      if (m == kInvalidDisp) continue;
      out.at(x, y) = m;
      if (replaced) replaced->at(x, y) = 1;
    }
  }
  return out;
}

}  // namespace fs
