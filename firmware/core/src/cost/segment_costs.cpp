// Data costs per segment and disparity: NCC (eq. 1) -> Data Cost 1 (eq. 8); NMI (eq. 2-4) and
// IGSAD (eq. 5-7) -> Data Cost 2 (eq. 9, combined in wta/).
//
// Layout of the search. For the reference pixel x of row y the partner pixel in the other image is
// x - d (left reference, direction +1) or x + d (right reference, direction -1), clamped to the
// image (border replicated). Per row, the other image is stored "padded and ordered by d":
//   O[y][base(x) + d] = other(y, clamp(x - direction*d))
// with base(x) = W-1-x (left reference, reversed row) or base(x) = x (right reference). The D
// partners of one pixel are therefore contiguous, and the per-pixel loop over d is a plain
// SIMD-friendly loop (int32 lanes). Sums over the partners alone (sum r, sum r^2) are taken per run
// from row prefix sums of O: a run [x0, x1) maps to O indices [lo + d, hi + d).
//
// Fixed-point formats and overflow bounds (n = segment pixels, any n < 2^24):
//   sum l, sum l^2, sum r, sum r^2     int64       (<= n * 65025)
//   sum r, sum r^2, sum l*r, sum |gl - gr| per d
//                                      int32 lanes, flushed into int64 before they hold more than
//                                      kFlushPixels pixels: kFlushPixels * 65025 < 2^31
//   NCC numerator and variances        int64, exact: n*Slr <= n^2 * 65025 < 2^63 for n < 2^24;
//                                      normalised once per (segment, d) in double -> Q16
//   entropies                          Q16 bits from the n*log2(n) table (uint64)
//   NMI, IGSAD                         Q16 in [0, 1]
#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <numeric>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {

constexpr int kFlushPixels = 32768;  // 32768 * 65025 < 2^31

// Padded partner rows of one image for one direction.
struct PartnerRows {
  int stride = 0;                       // W + D - 1
  std::vector<std::int16_t> val;        // O: grey value
  std::vector<std::int16_t> grad;       // gradient magnitude
  std::vector<std::uint8_t> bin;        // NMI bin of the grey value
  std::vector<std::int32_t> pre, pre2;  // row prefix sums of O and O^2, stride + 1 per row
                                        // (<= (W + D) * 65025 < 2^31 for W + D <= 33000)
};

void build_partner_rows(PartnerRows& p, const ImageU8& other, const ImageU16& other_grad, int direction, int D, int bins) {
  const int w = other.width, h = other.height;
  p.stride = w + D - 1;
  const std::size_t n = std::size_t(h) * std::size_t(p.stride);
  p.val.resize(n);
  p.grad.resize(n);
  p.bin.resize(n);
  p.pre.resize(std::size_t(h) * std::size_t(p.stride + 1));
  p.pre2.resize(p.pre.size());
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* src = other.row(y);
    const std::uint16_t* gsrc = other_grad.row(y);
    std::int16_t* v = p.val.data() + std::size_t(y) * std::size_t(p.stride);
    std::int16_t* g = p.grad.data() + std::size_t(y) * std::size_t(p.stride);
    std::uint8_t* b = p.bin.data() + std::size_t(y) * std::size_t(p.stride);
    for (int j = 0; j < p.stride; ++j) {
      // left reference: O[j] = other[W-1-j] (clamped at 0); right reference: O[j] = other[min(j, W-1)]
      const int x = direction > 0 ? std::max(0, w - 1 - j) : std::min(j, w - 1);
      v[j] = static_cast<std::int16_t>(src[x]);
      g[j] = static_cast<std::int16_t>(gsrc[x]);
      b[j] = static_cast<std::uint8_t>((src[x] * bins) >> 8);
    }
    std::int32_t* pr = p.pre.data() + std::size_t(y) * std::size_t(p.stride + 1);
    std::int32_t* pr2 = p.pre2.data() + std::size_t(y) * std::size_t(p.stride + 1);
    std::int32_t acc = 0, acc2 = 0;  // running sums in registers (no store-to-load chain)
    pr[0] = pr2[0] = 0;
    for (int j = 0; j < p.stride; ++j) {
      acc += v[j];
      acc2 += v[j] * v[j];
      pr[j + 1] = acc;
      pr2[j + 1] = acc2;
    }
  }
}

// The hot loop: for one reference pixel (l, gl), accumulate l*r and |gl - gr| over all d.
FS_TARGET_CLONES
void accumulate_pixel(std::int32_t l, std::int32_t gl, const std::int16_t* __restrict o,
                      const std::int16_t* __restrict og, std::int32_t* __restrict slr,
                      std::int32_t* __restrict sg, int D) {
  for (int d = 0; d < D; ++d) {
    slr[d] += l * o[d];
    sg[d] += std::abs(gl - og[d]);
  }
}

// Partner-only sums of one run for all d, from the row prefix sums: O[lo + d .. hi + d).
FS_TARGET_CLONES
void accumulate_run(const std::int32_t* __restrict pre, const std::int32_t* __restrict pre2, int lo, int hi,
                    std::int32_t* __restrict sr, std::int32_t* __restrict srr, int D) {
  for (int d = 0; d < D; ++d) {
    sr[d] += pre[hi + d] - pre[lo + d];
    srr[d] += pre2[hi + d] - pre2[lo + d];
  }
}

// eq. (1): NCC in Q16 from the exact integer sums, clamped to [0, 1] (Data Cost 1, eq. 8).
//   num = n*Slr - Sl*Sr, var_l = n*Sll - Sl^2, var_r = n*Srr - Sr^2 (int64, exact)
//   NCC = num / sqrt(var_l * var_r), evaluated once per (segment, d) in IEEE double (sqrt and
//   division are correctly rounded on x86-64 and AArch64 alike, so results are bit-identical) and
//   rounded to Q16. The per-pixel work stays integer; this normalisation is 1/n of it.
inline std::uint32_t ncc_q16(std::int64_t num, std::int64_t varr, double varl) {
  if (num <= 0 || varr <= 0 || varl <= 0.0) return 0;
  const double q = static_cast<double>(num) / std::sqrt(varl * static_cast<double>(varr));
  return q >= 1.0 ? static_cast<std::uint32_t>(kQ16One) : static_cast<std::uint32_t>(q * kQ16One + 0.5);
}

// eq. (7): IGSAD = 1 - GSAD_d / max_d GSAD in Q16, 65536 - trunc(GSAD_d * (65536 / max)) with the
// reciprocal in double (one division per segment instead of one per disparity).
inline std::uint32_t igsad_q16(std::int64_t g, double inv_max_q16) {
  return static_cast<std::uint32_t>(kQ16One - static_cast<std::int64_t>(static_cast<double>(g) * inv_max_q16));
}

}  // namespace

struct CostScratch {
  PartnerRows rows;
};

std::shared_ptr<CostScratch> make_cost_scratch() { return std::make_shared<CostScratch>(); }

SegmentCosts compute_segment_costs(const ImageU8& ref, const ImageU8& other, const ImageU16& ref_grad,
                                   const ImageU16& other_grad, const Segmentation& seg, int direction,
                                   const CostParams& p, const FisLut& fis, int threads, CostScratch* scratch) {
  const int w = ref.width, D = p.max_disparity, B = p.nmi_bins;
  const int shift = p.inject_shift;  // test-only fault injection; 0 in every real config
  CostScratch local;
  PartnerRows& pr = (scratch ? scratch : &local)->rows;
  build_partner_rows(pr, other, other_grad, direction, D + std::abs(shift), B);
  SegmentCosts c;
  c.segments = seg.count;
  c.disparities = D;
  const std::size_t total = std::size_t(seg.count) * std::size_t(D);
  c.ncc.assign(total, 0);
  c.igsad.assign(total, 0);
  c.nmi.assign(total, 0);
  c.nmi_valid.assign(total, 0);

  std::int32_t max_pixels = 0;
  for (auto n : seg.pixels) max_pixels = std::max(max_pixels, n);
  const std::vector<std::uint64_t> T = detail::nlogn_table_q16(std::size_t(max_pixels));
  const int K = (p.nmi_candidates <= 0 || p.nmi_candidates >= D) ? D : p.nmi_candidates;
  const auto base_of = [&](int x) { return (direction > 0 ? w - 1 - x : x) + (shift > 0 ? shift : 0); };

  const int nt = detail::resolve_threads(threads);
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel num_threads(nt)
#endif
  {
    (void)nt;
    std::vector<std::int32_t> slr32(static_cast<std::size_t>(D)), sg32(static_cast<std::size_t>(D));
    std::vector<std::int32_t> sr32(static_cast<std::size_t>(D)), srr32(static_cast<std::size_t>(D));
    std::vector<std::int64_t> slr(static_cast<std::size_t>(D)), sg(static_cast<std::size_t>(D)), sr(static_cast<std::size_t>(D)), srr(static_cast<std::size_t>(D));
    std::vector<std::uint32_t> joint(static_cast<std::size_t>(B * B)), hy(static_cast<std::size_t>(B)), hx(static_cast<std::size_t>(B));
    std::vector<std::uint32_t> prescore(static_cast<std::size_t>(D));
    std::vector<int> order(static_cast<std::size_t>(D));
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(dynamic, 32)
#endif
    for (int s = 0; s < seg.count; ++s) {
      const Run* r0 = seg.runs.data() + seg.run_begin[std::size_t(s)];
      const Run* r1 = seg.runs.data() + seg.run_begin[std::size_t(s) + 1];
      std::fill(slr.begin(), slr.end(), 0); std::fill(sg.begin(), sg.end(), 0);
      std::fill(sr.begin(), sr.end(), 0); std::fill(srr.begin(), srr.end(), 0);
      std::fill(slr32.begin(), slr32.end(), 0); std::fill(sg32.begin(), sg32.end(), 0);
      std::fill(sr32.begin(), sr32.end(), 0); std::fill(srr32.begin(), srr32.end(), 0);
      const auto flush = [&] {
        for (int d = 0; d < D; ++d) {
          const std::size_t i = std::size_t(d);
          slr[i] += slr32[i]; sg[i] += sg32[i]; sr[i] += sr32[i]; srr[i] += srr32[i];
          slr32[i] = sg32[i] = sr32[i] = srr32[i] = 0;
        }
      };
      std::int64_t n = 0, sl = 0, sll = 0;
      int since_flush = 0;
      for (const Run* r = r0; r != r1; ++r) {
        const std::uint8_t* lrow = ref.row(r->y);
        const std::uint16_t* grow = ref_grad.row(r->y);
        const std::size_t ro = std::size_t(r->y) * std::size_t(pr.stride);
        const std::int16_t* orow = pr.val.data() + ro;
        const std::int16_t* ogrow = pr.grad.data() + ro;
        // Partner-only sums from prefix sums: the run's partners at d are O[lo + d .. hi + d).
        const int lo = std::min(base_of(r->x0), base_of(r->x1 - 1));
        const int hi = std::max(base_of(r->x0), base_of(r->x1 - 1)) + 1;
        const std::int32_t* pre = pr.pre.data() + std::size_t(r->y) * std::size_t(pr.stride + 1);
        const std::int32_t* pre2 = pr.pre2.data() + std::size_t(r->y) * std::size_t(pr.stride + 1);
        const int len = r->x1 - r->x0;  // <= W <= kFlushPixels (checked by the Matcher)
        if (since_flush + len > kFlushPixels) {
          flush();
          since_flush = 0;
        }
        since_flush += len;
        accumulate_run(pre, pre2, lo, hi, sr32.data(), srr32.data(), D);
        const int b0 = base_of(r->x0), step = direction > 0 ? -1 : 1;
        for (int x = r->x0, b = b0; x < r->x1; ++x, b += step) {
          const std::int32_t l = lrow[x];
          sl += l;
          sll += l * l;
          accumulate_pixel(l, grow[x], orow + b, ogrow + b, slr32.data(), sg32.data(), D);
        }
        n += len;
      }
      flush();

      // eq. (1) NCC and eq. (6)-(7) IGSAD.
      const std::size_t off = std::size_t(s) * std::size_t(D);
      const auto varl = static_cast<double>(n * sll - sl * sl);
      std::int64_t gmax = 0;
      for (int d = 0; d < D; ++d) gmax = std::max(gmax, sg[std::size_t(d)]);
      const double inv_gmax = gmax > 0 ? static_cast<double>(kQ16One) / static_cast<double>(gmax) : 0.0;
      for (int d = 0; d < D; ++d) {
        const std::size_t i = std::size_t(d);
        c.ncc[off + i] = ncc_q16(n * slr[i] - sl * sr[i], n * srr[i] - sr[i] * sr[i], varl);
        c.igsad[off + i] = igsad_q16(sg[i], inv_gmax);
      }

      // Candidates for NMI: the K best by FIS(NCC, IGSAD) read at the nearest table node (ranking
      // needs no interpolation); ties -> smaller d.
      std::iota(order.begin(), order.end(), 0);
      if (K < D) {
        for (int d = 0; d < D; ++d)
          prescore[std::size_t(d)] = fis.lookup_nearest(c.ncc[off + std::size_t(d)], c.igsad[off + std::size_t(d)]);
        const auto better = [&](int a, int b) {
          return prescore[std::size_t(a)] != prescore[std::size_t(b)] ? prescore[std::size_t(a)] > prescore[std::size_t(b)] : a < b;
        };
        std::nth_element(order.begin(), order.begin() + (K - 1), order.end(), better);
        std::sort(order.begin(), order.begin() + K, better);
      }

      // eq. (2)-(4): NMI from the joint histogram; entropies kept incrementally with T[c].
      std::fill(hx.begin(), hx.end(), 0);
      std::uint64_t sum_tx = 0;
      for (const Run* r = r0; r != r1; ++r) {
        const std::uint8_t* lrow = ref.row(r->y);
        for (int x = r->x0; x < r->x1; ++x) {
          std::uint32_t& cx = hx[std::size_t((lrow[x] * B) >> 8)];
          sum_tx += T[cx + 1] - T[cx];
          ++cx;
        }
      }
      const std::uint64_t un = static_cast<std::uint64_t>(n);
      const std::uint64_t H_x = detail::entropy_q16(T, un, sum_tx);
      for (int k = 0; k < K; ++k) {
        const int d = order[std::size_t(k)];
        std::fill(joint.begin(), joint.end(), 0);
        std::fill(hy.begin(), hy.end(), 0);
        std::uint64_t sum_txy = 0, sum_ty = 0;
        for (const Run* r = r0; r != r1; ++r) {
          const std::uint8_t* lrow = ref.row(r->y);
          const std::uint8_t* brow = pr.bin.data() + std::size_t(r->y) * std::size_t(pr.stride);
          for (int x = r->x0; x < r->x1; ++x) {
            const int by = brow[base_of(x) + d];
            const int bx = (lrow[x] * B) >> 8;
            std::uint32_t& cxy = joint[std::size_t(bx * B + by)];
            sum_txy += T[cxy + 1] - T[cxy];
            ++cxy;
            std::uint32_t& cy = hy[std::size_t(by)];
            sum_ty += T[cy + 1] - T[cy];
            ++cy;
          }
        }
        const std::uint64_t H_y = detail::entropy_q16(T, un, sum_ty);
        const std::uint64_t H_xy = detail::entropy_q16(T, un, sum_txy);
        std::uint32_t nmi = 0;
        const std::uint64_t den = detail::isqrt64(H_x * H_y);  // Q16
        if (den > 0 && H_x + H_y > H_xy) {
          const std::uint64_t q = ((H_x + H_y - H_xy) << kQ16Shift) / den;
          nmi = static_cast<std::uint32_t>(std::min<std::uint64_t>(q, kQ16One));
        }
        c.nmi[off + std::size_t(d)] = nmi;
        c.nmi_valid[off + std::size_t(d)] = 1;
      }
    }
  }
  return c;
}

}  // namespace fs
