// Data costs per segment and disparity: NCC (eq. 1) -> Data Cost 1 (eq. 8); NMI (eq. 2-4) and
// IGSAD (eq. 5-7) -> Data Cost 2 (eq. 9, combined in wta/).
//
// Layout of the search. For the reference pixel x of row y the partner pixel in the other image is
// x - d (left reference, direction +1) or x + d (right reference, direction -1), clamped to the
// image (border replicated). Per row, the other image is stored "padded and ordered by d":
//   O[y][base(x) + d] = other(y, clamp(x - direction*d))
// with base(x) = W-1-x (left reference, reversed row) or base(x) = x (right reference). The D
// partners of one pixel are therefore contiguous. Sums over the partners alone (sum r, sum r^2)
// are taken per run from row prefix sums of O: a run [x0, x1) maps to O indices [lo + d, hi + d).
//
// The per-pixel sums (sum l*r, sum |gl - gr|) are register-blocked: per segment the pixels are
// listed once (offset into O, l, gl, NMI bin), then for each block of kBlock disparities one pass
// over the list keeps the 2*kBlock int32 accumulators in vector registers (no load/store of a
// D-long accumulator array per pixel). Rows are padded by kBlock partners so the last block reads
// inside the row; its lanes beyond D are discarded.
//
// Fixed-point formats and overflow bounds (n = segment pixels, any n < 2^24):
//   sum l, sum l^2, sum r, sum r^2     int64       (<= n * 65025)
//   l*r per pixel                      uint16 lane (l, r <= 255: l*r <= 65025 < 2^16)
//   |gl - gr| per pixel                int16 lane  (gradients <= 1443)
//   sum r, sum r^2, sum l*r, sum |gl - gr| per d
//                                      int32 lanes, flushed into int64 before they hold more than
//                                      kFlushPixels pixels: kFlushPixels * 65025 < 2^31
//   NCC numerator and variances        int64, exact: n*Slr <= n^2 * 65025 < 2^63 for n < 2^24;
//                                      normalised once per (segment, d) in double -> Q16
//   entropies                          Q16 bits from the n*log2(n) table (uint64)
//   NMI, IGSAD                         Q16 in [0, 1]
#include <algorithm>
#include <bit>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <numeric>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {

constexpr int kFlushPixels = 32768;  // 32768 * 65025 < 2^31 (and 32768 * 1443 < 2^31)
constexpr int kNmiGroup = 4;         // NMI candidates evaluated per pass over a segment's pixels
constexpr int kBlock = 32;           // disparities per register block: 2 x 32 int32 lanes = 8 AVX2 registers

// Padded partner rows of one image for one direction.
struct PartnerRows {
  int stride = 0;                       // W + D + kBlock - 1 (see build_partner_rows)
  std::vector<std::uint16_t> val;       // O: grey value (0..255)
  std::vector<std::int16_t> grad;       // gradient magnitude (0..1443)
  std::vector<std::uint8_t> bin;        // NMI bin of the grey value
  int pre_stride = 0;                    // = stride + 1: pre[j] = sum of O[0 .. j)
  std::vector<std::uint32_t> pre, pre2;  // row prefix sums of O and O^2 over every partner, the
                                         // block padding included, modulo 2^32: a difference
                                         // pre[hi] - pre[lo] (uint32) is exact while the true sum
                                         // is < 2^32, whatever the row length
};

// D is the number of disparities searched (with the test-only shift). The rows hold D + kBlock
// partners per pixel, so a block of kBlock disparities starting at any d0 < D reads inside the row.
FS_TARGET_CLONES_V4
void build_partner_rows(PartnerRows& p, const ImageU8& other, const ImageU16& other_grad, int direction, int D, int bins) {
  const int w = other.width, h = other.height;
  p.stride = w + D + kBlock - 1;
  const std::size_t n = std::size_t(h) * std::size_t(p.stride);
  p.val.resize(n);
  p.grad.resize(n);
  p.bin.resize(n);
  p.pre_stride = p.stride + 1;
  p.pre.resize(std::size_t(h) * std::size_t(p.pre_stride));
  p.pre2.resize(p.pre.size());
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* src = other.row(y);
    const std::uint16_t* gsrc = other_grad.row(y);
    std::uint16_t* v = p.val.data() + std::size_t(y) * std::size_t(p.stride);
    std::int16_t* g = p.grad.data() + std::size_t(y) * std::size_t(p.stride);
    std::uint8_t* b = p.bin.data() + std::size_t(y) * std::size_t(p.stride);
    // left reference: O[j] = other[W-1-j] (clamped at 0); right reference: O[j] = other[min(j, W-1)].
    // The first W partners are the row (reversed or not), the rest repeat its border pixel: two
    // branch-free loops that vectorise.
    const int edge = direction > 0 ? 0 : w - 1;
    for (int j = 0; j < w; ++j) {
      const int x = direction > 0 ? w - 1 - j : j;
      v[j] = src[x];
      g[j] = static_cast<std::int16_t>(gsrc[x]);
    }
    for (int j = w; j < p.stride; ++j) {
      v[j] = src[edge];
      g[j] = static_cast<std::int16_t>(gsrc[edge]);
    }
    for (int j = 0; j < p.stride; ++j) b[j] = static_cast<std::uint8_t>((v[j] * bins) >> 8);
    std::uint32_t* pr = p.pre.data() + std::size_t(y) * std::size_t(p.pre_stride);
    std::uint32_t* pr2 = p.pre2.data() + std::size_t(y) * std::size_t(p.pre_stride);
    std::uint32_t acc = 0, acc2 = 0;  // running sums in registers (no store-to-load chain)
    pr[0] = pr2[0] = 0;
    for (int j = 0; j + 1 < p.pre_stride; ++j) {
      acc += v[j];
      acc2 += std::uint32_t(v[j]) * v[j];
      pr[j + 1] = acc;
      pr2[j + 1] = acc2;
    }
  }
}

// One reference pixel of a segment: its partners start at O[off] (row offset + base(x)).
struct SegPixel {
  std::int32_t off;
  std::uint16_t gl;  // gradient magnitude, <= 1443
  std::uint8_t l;    // grey value
  std::uint8_t bx;   // NMI bin of l
};

// The hot loop: for n pixels and the kBlock disparities starting at val/grad + off, the sums of
// l*r and |gl - gr| (n <= kFlushPixels). The per-pixel terms are added in 16-bit lanes, so no lane
// is widened per pixel (widening is a cross-lane shuffle on x86 and the bottleneck of the loop):
//   l*r (<= 65025, exact in uint16) is split as 256*hi + lo, hi = p >> 8 <= 254, lo = p & 255;
//   hi, l*r itself (modulo 2^16) and |gl - gr| (<= 1443) are summed in uint16 over groups of
//   kGroup16 pixels (kGroup16 * 1443 < 2^16), sum lo is recovered per group from the first two
//   (see below), and each group's sums are widened once into the int32 totals
//   (sum l*r = 256 * sum hi + sum lo; n <= kFlushPixels keeps the totals < 2^31).
constexpr int kGroup16 = 45;  // 45 * 1443 = 64935 < 65536 (and 45 * 255 for hi, lo)

FS_TARGET_CLONES_V4 FS_NO_MEMSET_PATTERNS
void accumulate_block(const SegPixel* __restrict px, int n, const std::uint16_t* __restrict val,
                      const std::int16_t* __restrict grad, std::int32_t* __restrict slr, std::int32_t* __restrict sg) {
  std::int32_t a[kBlock], g[kBlock];
  for (int j = 0; j < kBlock; ++j) a[j] = g[j] = 0;
  for (int i0 = 0; i0 < n; i0 += kGroup16) {
    const int i1 = std::min(n, i0 + kGroup16);
    std::uint16_t hi[kBlock], wrap[kBlock], g16[kBlock];
    for (int j = 0; j < kBlock; ++j) hi[j] = wrap[j] = g16[j] = 0;
    for (int i = i0; i < i1; ++i) {
      const std::uint16_t* o = val + px[i].off;
      const std::int16_t* og = grad + px[i].off;
      const std::uint16_t l = px[i].l;
      const auto gl = static_cast<std::int16_t>(px[i].gl);
      for (int j = 0; j < kBlock; ++j) {
        const auto prod = static_cast<std::uint16_t>(l * o[j]);
        hi[j] = static_cast<std::uint16_t>(hi[j] + (prod >> 8));
        wrap[j] = static_cast<std::uint16_t>(wrap[j] + prod);  // sum of l*r modulo 2^16
        g16[j] = static_cast<std::uint16_t>(g16[j] + static_cast<std::uint16_t>(std::abs(static_cast<std::int16_t>(gl - og[j]))));
      }
    }
    // sum lo = sum (p & 255) < kGroup16 * 256 < 2^16, and sum lo = sum p - 256 sum hi, so it is
    // (wrap - 256 hi) modulo 2^16 exactly: the loop needs no mask per pixel.
    for (int j = 0; j < kBlock; ++j) {
      const auto lo = static_cast<std::uint16_t>(wrap[j] - static_cast<std::uint16_t>(hi[j] << 8));
      a[j] += (std::int32_t(hi[j]) << 8) + lo;
      g[j] += g16[j];
    }
  }
  for (int j = 0; j < kBlock; ++j) {
    slr[j] = a[j];
    sg[j] = g[j];
  }
}

// eq. (2)-(4) for kNmiGroup (= 4) candidates, in two passes:
//   1. histograms: per pixel one increment of each candidate's joint histogram (bin of l, bin of
//      the candidate's partner), and with kPartnerHistograms of its partner histogram — a single
//      read-modify-write each;
//   2. sums: sum_c T[c] over each histogram, reading every nonzero cell once and clearing it for
//      the next group (T[0] = 0, so the zero cells add nothing and need no branch).
// Pass 2 walks whichever is shorter: the joint histograms' touched rows (bx_lo .. bx_hi, cell by
// cell; the partner histograms are then their column sums, so pass 1 skips them), or the pixel
// list again (each pixel's cell, read and cleared: a cell's count is taken by its first pixel, the
// rest read 0). Both give the same integers as summing T over the histogram.
static_assert(kNmiGroup == 4, "nmi_group_histograms is written for 4 candidates");
template <bool kPartnerHistograms>
void nmi_group_histograms(const SegPixel* __restrict px, std::size_t n, const std::uint8_t* const* bin, int B,
                          std::uint32_t* __restrict joint, std::uint32_t* __restrict hy) {
  const std::size_t BB = std::size_t(B) * std::size_t(B);
  std::uint32_t* __restrict j0 = joint;
  std::uint32_t* __restrict j1 = joint + BB;
  std::uint32_t* __restrict j2 = joint + 2 * BB;
  std::uint32_t* __restrict j3 = joint + 3 * BB;
  const std::uint8_t *b0 = bin[0], *b1 = bin[1], *b2 = bin[2], *b3 = bin[3];
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t off = static_cast<std::size_t>(px[i].off);
    const std::size_t row = std::size_t(px[i].bx) * std::size_t(B);
    const std::size_t c0 = b0[off], c1 = b1[off], c2 = b2[off], c3 = b3[off];
    ++j0[row + c0];
    ++j1[row + c1];
    ++j2[row + c2];
    ++j3[row + c3];
    if constexpr (kPartnerHistograms) {
      ++hy[c0];
      ++hy[std::size_t(B) + c1];
      ++hy[2 * std::size_t(B) + c2];
      ++hy[3 * std::size_t(B) + c3];
    }
  }
}

// sum_c T[c] over the `rows` rows of B cells at `cells`, clearing them, and their column sums added
// into col[0 .. B) (the partner histogram is the joint histogram's column sums).
inline std::uint64_t take_sum_t_rows(std::uint32_t* __restrict cells, int rows, int B, const std::uint64_t* __restrict T,
                                     std::uint32_t* __restrict col) {
  std::uint64_t s = 0;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < B; ++c) {
      std::uint32_t& v = cells[std::size_t(r) * std::size_t(B) + std::size_t(c)];
      s += T[v];
      col[c] += v;
      v = 0;
    }
  return s;
}

// sum_c T[c] over cells[0 .. count), clearing them.
inline std::uint64_t take_sum_t(std::uint32_t* __restrict cells, std::size_t count, const std::uint64_t* __restrict T) {
  std::uint64_t s = 0;
  for (std::size_t i = 0; i < count; ++i) {
    s += T[cells[i]];
    cells[i] = 0;
  }
  return s;
}

// sum_c T[c] over the joint histograms of the group through the pixel list (pass 2, pixel walk).
void take_joint_sums_by_pixels(const SegPixel* __restrict px, std::size_t n, const std::uint8_t* const* bin, int B,
                               std::uint32_t* __restrict joint, const std::uint64_t* __restrict T,
                               std::uint64_t* sum_txy) {
  const std::size_t BB = std::size_t(B) * std::size_t(B);
  const std::uint8_t *b0 = bin[0], *b1 = bin[1], *b2 = bin[2], *b3 = bin[3];
  std::uint64_t x0 = 0, x1 = 0, x2 = 0, x3 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t off = static_cast<std::size_t>(px[i].off);
    const std::size_t row = std::size_t(px[i].bx) * std::size_t(B);
    std::uint32_t& a0 = joint[row + b0[off]];          x0 += T[a0]; a0 = 0;
    std::uint32_t& a1 = joint[BB + row + b1[off]];     x1 += T[a1]; a1 = 0;
    std::uint32_t& a2 = joint[2 * BB + row + b2[off]]; x2 += T[a2]; a2 = 0;
    std::uint32_t& a3 = joint[3 * BB + row + b3[off]]; x3 += T[a3]; a3 = 0;
  }
  sum_txy[0] = x0; sum_txy[1] = x1; sum_txy[2] = x2; sum_txy[3] = x3;
}

// Partner-only sums of a segment for all d, from the row prefix sums: run i covers O[lo + d ..
// hi + d) of its row. Register-blocked like accumulate_block: per block of kBlock disparities one
// pass over the run list keeps the 2*kBlock accumulators in registers. The last block's lanes
// beyond D read the padding partners (inside the row) and are not stored. uint32 (modular) lanes:
// each real lane is exact while its sum is < 2^32 (the caller passes at most kFlushPixels pixels:
// sum r^2 <= kFlushPixels * 65025 < 2^31).
struct RunSpan {
  const std::uint32_t* pre;   // row prefix sums of O ...
  const std::uint32_t* pre2;  // ... and of O^2
  std::int32_t lo, hi;
};

FS_TARGET_CLONES_V4 FS_NO_MEMSET_PATTERNS
void accumulate_runs(const RunSpan* __restrict runs, int nruns, int D, std::int32_t* __restrict sr,
                     std::int32_t* __restrict srr) {
  for (int d0 = 0; d0 < D; d0 += kBlock) {
    std::uint32_t a[kBlock], b[kBlock];
    for (int j = 0; j < kBlock; ++j) a[j] = b[j] = 0;
    for (int i = 0; i < nruns; ++i) {
      const std::uint32_t* __restrict ph = runs[i].pre + runs[i].hi + d0;
      const std::uint32_t* __restrict pl = runs[i].pre + runs[i].lo + d0;
      const std::uint32_t* __restrict qh = runs[i].pre2 + runs[i].hi + d0;
      const std::uint32_t* __restrict ql = runs[i].pre2 + runs[i].lo + d0;
      for (int j = 0; j < kBlock; ++j) {
        a[j] += ph[j] - pl[j];
        b[j] += qh[j] - ql[j];
      }
    }
    const int nb = std::min(kBlock, D - d0);
    for (int j = 0; j < nb; ++j) {
      sr[d0 + j] = static_cast<std::int32_t>(a[j]);
      srr[d0 + j] = static_cast<std::int32_t>(b[j]);
    }
  }
}

// max_d GSAD_d, the normaliser of eq. (7) (a max reduction that vectorises).
FS_TARGET_CLONES_V4
std::int32_t max_of(const std::int32_t* __restrict v, int D) {
  std::int32_t m = 0;
  for (int d = 0; d < D; ++d) m = std::max(m, v[d]);
  return m;
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

// eq. (1) and eq. (7) for all D of one segment whose sums fit int32 (n <= kFlushPixels, the case
// of every SLIC segment in practice): the same double operations as ncc_q16/igsad_q16, written
// branch-free so they vectorise. Every integer below is exact in double (n <= 2^15, sums < 2^31:
// products < 2^46), so the results are bit-identical to the int64 path.
FS_TARGET_CLONES_V4
void ncc_igsad_q16_i32(const std::int32_t* __restrict slr, const std::int32_t* __restrict sr,
                       const std::int32_t* __restrict srr, const std::int32_t* __restrict sg, int D, double n,
                       double sl, double varl, double inv_gmax, std::uint32_t* __restrict ncc,
                       std::uint32_t* __restrict igsad) {
  const double vl = varl > 0.0 ? varl : 0.0;  // varl <= 0 (flat segment): NCC = 0 for every d
  for (int d = 0; d < D; ++d) {
    const double r = sr[d];
    const double num = n * slr[d] - sl * r;
    const double varr = n * srr[d] - r * r;
    const double den = std::sqrt(vl * varr);
    const bool ok = (num > 0.0) & (varr > 0.0) & (vl > 0.0);
    const double q0 = num / den;  // inf/NaN where !ok: computed for every d, then masked
    const double q = ok ? q0 : 0.0;
    const double v = std::min(q, 1.0);
    ncc[d] = static_cast<std::uint32_t>(static_cast<std::int32_t>(v * kQ16One + 0.5));
    igsad[d] = static_cast<std::uint32_t>(kQ16One - static_cast<std::int32_t>(static_cast<double>(sg[d]) * inv_gmax));
  }
}

// FIS score at the nearest table node for every d (FisLut::lookup_nearest, written as one loop of
// index arithmetic and table reads so it vectorises with gathers).
FS_TARGET_CLONES_V4
void prescore_nearest(const FisLut& fis, const std::uint32_t* __restrict a, const std::uint32_t* __restrict b, int D,
                      std::uint32_t* __restrict out) {
  const std::uint32_t* __restrict table = fis.table().data();
  const auto n1 = static_cast<std::uint32_t>(fis.size() - 1), size = static_cast<std::uint32_t>(fis.size());
  for (int d = 0; d < D; ++d) {
    const std::uint32_t ia = (std::min<std::uint32_t>(a[d], 1u << 16) * n1 + (1u << 15)) >> 16;
    const std::uint32_t ib = (std::min<std::uint32_t>(b[d], 1u << 16) * n1 + (1u << 15)) >> 16;
    out[d] = table[ia * size + ib];
  }
}

// The K-th largest of m values: the one whose rank (number of values before it in the order
// value desc, index asc) is K - 1. Branch-free all-pairs ranks; for m = 16 a few vector
// instructions instead of nth_element's data-dependent branches.
inline std::uint32_t kth_largest(const std::uint32_t* v, int m, int K) {
  std::uint32_t out = 0;
  for (int i = 0; i < m; ++i) {
    int rank = 0;
    for (int j = 0; j < m; ++j) rank += (v[j] > v[i]) | ((v[j] == v[i]) & (j < i));
    out = rank == K - 1 ? v[i] : out;
  }
  return out;
}

// Lower bound of the K-th largest prescore: the K-th largest of the maxima of M = 2K disjoint
// classes of disparities (K values at distinct positions, one per class, are >= it; M = K when
// D < 4K); 0 when D < 2K. The classes are the residues d mod M, so the class maxima are one
// vertical max over rows of M lanes (vectorises, M = 16 for the default K = 8 has its own
// fixed-width loop), and neighbouring disparities — a prescore peak is a few d wide — fall into
// different classes, which keeps the bound close to the K-th value.
FS_TARGET_CLONES_V4
std::uint32_t top_k_threshold(const std::uint32_t* __restrict prescore, int D, int K) {
  if (D < 2 * K || K > 32) return 0;
  const int M = D >= 4 * K ? 2 * K : K;
  std::uint32_t mx[64] = {};
  int d0 = 0;
  if (M == 16) {  // the default K = 8: fixed-width rows of 16 lanes
    for (; d0 + 16 <= D; d0 += 16)
      for (int k = 0; k < 16; ++k) mx[k] = std::max(mx[k], prescore[d0 + k]);
  }
  for (int d = d0; d < D; ++d) mx[d % M] = std::max(mx[d % M], prescore[d]);
  return kth_largest(mx, M, K);
}

// Flags of the disparities that reach thr (1 byte per d, vectorises); the flag array is padded
// with zeros to a multiple of 8 so it can be read 8 flags at a time.
FS_TARGET_CLONES_V4
void flag_at_least(const std::uint32_t* __restrict prescore, int D, std::uint32_t thr, std::uint8_t* __restrict flag) {
  for (int d = 0; d < D; ++d) flag[d] = prescore[d] >= thr ? 1 : 0;
  for (int d = D; d % 8 != 0; ++d) flag[d] = 0;
}

// The K best disparities by (prescore desc, d asc), best first: one pass keeping a sorted list of
// K (most disparities lose against the K-th best with one comparison).
//   key = prescore * 2^32 + (2^32 - 1 - d): larger key = better, ties -> smaller d.
// Disparities below top_k_threshold cannot be among the K best (at least K prescores reach it):
// only the flagged ones are visited, found 8 flags at a time from the lowest set byte (no
// per-disparity branch); the result is that of the full pass. flag: scratch of >= D + 8 bytes.
void top_k(const std::uint32_t* prescore, int D, int K, std::uint64_t* best, int* order, std::uint8_t* flag) {
  flag_at_least(prescore, D, top_k_threshold(prescore, D, K), flag);
  int m = 0;
  for (int d0 = 0; d0 < D; d0 += 8) {
    std::uint64_t bits;
    std::memcpy(&bits, flag + d0, sizeof bits);  // byte i = flag of d0 + i
    while (bits) {
      const int d = d0 + std::countr_zero(bits) / 8;  // little-endian word (static_assert in internal.hpp)
      bits &= bits - 1;  // each flag byte is 0 or 1: clears exactly that flag
      const std::uint64_t key = (std::uint64_t(prescore[d]) << 32) | (0xFFFFFFFFu - static_cast<std::uint32_t>(d));
      if (m == K && key <= best[K - 1]) continue;
      int j = m < K ? m++ : K - 1;
      for (; j > 0 && best[j - 1] < key; --j) best[j] = best[j - 1];
      best[j] = key;
    }
  }
  for (int k = 0; k < K; ++k) order[k] = static_cast<int>(0xFFFFFFFFu - static_cast<std::uint32_t>(best[k]));
}

}  // namespace

struct CostScratch {
  PartnerRows rows;
  SegmentCosts costs;  // the Matcher's output buffer (scratch_costs)
};

std::shared_ptr<CostScratch> make_cost_scratch() { return std::make_shared<CostScratch>(); }

SegmentCosts& scratch_costs(CostScratch& scratch) { return scratch.costs; }

SegmentCosts compute_segment_costs(const ImageU8& ref, const ImageU8& other, const ImageU16& ref_grad,
                                   const ImageU16& other_grad, const Segmentation& seg, int direction,
                                   const CostParams& p, const FisLut& fis, int threads, CostScratch* scratch) {
  SegmentCosts c;
  compute_segment_costs(c, ref, other, ref_grad, other_grad, seg, direction, p, fis, threads, scratch);
  return c;
}

void compute_segment_costs(SegmentCosts& c, const ImageU8& ref, const ImageU8& other, const ImageU16& ref_grad,
                           const ImageU16& other_grad, const Segmentation& seg, int direction, const CostParams& p,
                           const FisLut& fis, int threads, CostScratch* scratch) {
  const int w = ref.width, D = p.max_disparity, B = p.nmi_bins;
  const int shift = p.inject_shift;  // test-only fault injection; 0 in every real config
  CostScratch local;
  PartnerRows& pr = (scratch ? scratch : &local)->rows;
  build_partner_rows(pr, other, other_grad, direction, D + std::abs(shift), B);
  c.segments = seg.count;
  c.disparities = D;
  const std::size_t total = std::size_t(seg.count) * std::size_t(D);
  c.ncc.resize(total);    // every entry is written below (all D of every segment)
  c.igsad.resize(total);

  std::int32_t max_pixels = 0;
  for (auto n : seg.pixels) max_pixels = std::max(max_pixels, n);
  const std::vector<std::uint64_t> T = detail::nlogn_table_q16(std::size_t(max_pixels));
  const int K = (p.nmi_candidates <= 0 || p.nmi_candidates >= D) ? D : p.nmi_candidates;
  c.candidates_per_segment = K;
  c.candidates.resize(std::size_t(seg.count) * std::size_t(K));  // every record is written below
  const auto base_of = [&](int x) { return (direction > 0 ? w - 1 - x : x) + (shift > 0 ? shift : 0); };

  const int nt = detail::resolve_threads(threads);
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel num_threads(nt)
#endif
  {
    (void)nt;
    const auto uD = static_cast<std::size_t>(D);
    std::vector<std::int32_t> sr32(uD), srr32(uD), slr32(uD + kBlock), sg32(uD + kBlock);
    std::vector<std::int64_t> slr(uD), sg(uD), sr(uD), srr(uD);
    std::int32_t blr[kBlock], bg[kBlock];
    std::vector<SegPixel> px;
    std::vector<RunSpan> spans;
    std::vector<std::uint32_t> joint(std::size_t(kNmiGroup) * std::size_t(B * B), 0), hy(std::size_t(kNmiGroup * B), 0),
        hx(static_cast<std::size_t>(B));
    std::vector<std::uint32_t> prescore(uD);
    std::vector<std::uint64_t> best(uD);
    std::vector<std::uint8_t> flags(uD + 8);
    std::vector<int> order(uD);
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(dynamic, 32)
#endif
    for (int s = 0; s < seg.count; ++s) {
      const Run* r0 = seg.runs.data() + seg.run_begin[std::size_t(s)];
      const Run* r1 = seg.runs.data() + seg.run_begin[std::size_t(s) + 1];
      if (seg.pixels[std::size_t(s)] > kFlushPixels) {  // int64 sums only where int32 could overflow
        std::fill(slr.begin(), slr.end(), 0); std::fill(sg.begin(), sg.end(), 0);
        std::fill(sr.begin(), sr.end(), 0); std::fill(srr.begin(), srr.end(), 0);
      }

      // Pixel list, grey-value sums, H(x) histogram and the runs' partner spans. The partner-only
      // sums are taken over chunks of at most kFlushPixels pixels (int32 lanes); all but the last
      // chunk are added into the int64 sums, the last one stays in sr32/srr32.
      std::size_t npx = 0;
      for (const Run* r = r0; r != r1; ++r) npx += std::size_t(r->x1 - r->x0);
      px.resize(npx);
      SegPixel* __restrict out = px.data();
      spans.clear();
      std::int64_t sl = 0, sll = 0;
      int since_flush = 0;
      const int step = direction > 0 ? -1 : 1;  // base_of(x + 1) - base_of(x)
      for (const Run* r = r0; r != r1; ++r) {
        const std::uint8_t* lrow = ref.row(r->y);
        const std::uint16_t* grow = ref_grad.row(r->y);
        const auto ro = static_cast<std::int32_t>(std::size_t(r->y) * std::size_t(pr.stride));
        const int len = r->x1 - r->x0;  // <= W <= kFlushPixels (checked by the Matcher)
        if (since_flush + len > kFlushPixels) {
          accumulate_runs(spans.data(), static_cast<int>(spans.size()), D, sr32.data(), srr32.data());
          for (std::size_t i = 0; i < uD; ++i) { sr[i] += sr32[i]; srr[i] += srr32[i]; }
          spans.clear();
          since_flush = 0;
        }
        since_flush += len;
        // The run's partners at d are O[lo + d .. hi + d).
        const int lo = std::min(base_of(r->x0), base_of(r->x1 - 1));
        const int hi = std::max(base_of(r->x0), base_of(r->x1 - 1)) + 1;
        const std::size_t pre_row = std::size_t(r->y) * std::size_t(pr.pre_stride);
        spans.push_back({pr.pre.data() + pre_row, pr.pre2.data() + pre_row, lo, hi});
        std::int32_t o = ro + base_of(r->x0);
        std::int64_t rs = 0, rss = 0;  // the run's sums (< 2^31: len <= kFlushPixels)
        for (int x = r->x0; x < r->x1; ++x, o += step) {
          const std::int32_t l = lrow[x];
          rs += l;
          rss += l * l;
          const auto bx = static_cast<std::uint8_t>((l * B) >> 8);
          ++hx[bx];
          *out++ = {o, grow[x], static_cast<std::uint8_t>(l), bx};
        }
        sl += rs;
        sll += rss;
      }
      // H(x): sum_c T[c] over the grey-bin histogram (cleared for the next segment), and the rows
      // of the joint histograms this segment can touch.
      std::uint64_t sum_tx = 0;
      int bx_lo = B, bx_hi = -1;
      for (int b = 0; b < B; ++b) {
        if (hx[std::size_t(b)] == 0) continue;
        bx_lo = std::min(bx_lo, b);
        bx_hi = b;
        sum_tx += T[hx[std::size_t(b)]];
        hx[std::size_t(b)] = 0;
      }
      accumulate_runs(spans.data(), static_cast<int>(spans.size()), D, sr32.data(), srr32.data());
      const auto n = static_cast<std::int64_t>(px.size());

      // sum l*r and sum |gl - gr|, kBlock disparities at a time, kFlushPixels pixels at a time;
      // then eq. (1) NCC and eq. (6)-(7) IGSAD.
      const std::size_t off = std::size_t(s) * uD;
      const auto varl = static_cast<double>(n * sll - sl * sl);
      if (px.size() <= std::size_t(kFlushPixels)) {  // int32 sums (see ncc_igsad_q16_i32)
        for (int d0 = 0; d0 < D; d0 += kBlock)
          accumulate_block(px.data(), static_cast<int>(px.size()), pr.val.data() + d0, pr.grad.data() + d0,
                           slr32.data() + d0, sg32.data() + d0);
        const std::int32_t gmax = max_of(sg32.data(), D);
        const double inv_gmax = gmax > 0 ? static_cast<double>(kQ16One) / static_cast<double>(gmax) : 0.0;
        ncc_igsad_q16_i32(slr32.data(), sr32.data(), srr32.data(), sg32.data(), D, static_cast<double>(n),
                          static_cast<double>(sl), varl, inv_gmax, c.ncc.data() + off, c.igsad.data() + off);
      } else {
        for (std::size_t i = 0; i < uD; ++i) { sr[i] += sr32[i]; srr[i] += srr32[i]; }
        for (int d0 = 0; d0 < D; d0 += kBlock) {
          const int nb = std::min(kBlock, D - d0);
          for (std::size_t i0 = 0; i0 < px.size(); i0 += kFlushPixels) {
            const int cnt = static_cast<int>(std::min<std::size_t>(kFlushPixels, px.size() - i0));
            accumulate_block(px.data() + i0, cnt, pr.val.data() + d0, pr.grad.data() + d0, blr, bg);
            for (int j = 0; j < nb; ++j) {
              slr[std::size_t(d0 + j)] += blr[j];
              sg[std::size_t(d0 + j)] += bg[j];
            }
          }
        }
        std::int64_t gmax = 0;
        for (int d = 0; d < D; ++d) gmax = std::max(gmax, sg[std::size_t(d)]);
        const double inv_gmax = gmax > 0 ? static_cast<double>(kQ16One) / static_cast<double>(gmax) : 0.0;
        for (int d = 0; d < D; ++d) {
          const std::size_t i = std::size_t(d);
          c.ncc[off + i] = ncc_q16(n * slr[i] - sl * sr[i], n * srr[i] - sr[i] * sr[i], varl);
          c.igsad[off + i] = igsad_q16(sg[i], inv_gmax);
        }
      }

      // Candidates for NMI: the K best by FIS(NCC, IGSAD) read at the nearest table node (ranking
      // needs no interpolation; ties -> smaller d), then in ascending d (the record order).
      if (K < D) {
        prescore_nearest(fis, c.ncc.data() + off, c.igsad.data() + off, D, prescore.data());
        top_k(prescore.data(), D, K, best.data(), order.data(), flags.data());
        std::sort(order.begin(), order.begin() + K);
      } else {
        std::iota(order.begin(), order.end(), 0);
      }
      CostCandidate* rec = c.candidates.data() + std::size_t(s) * std::size_t(K);

      // eq. (2)-(4): NMI from the joint histogram, kNmiGroup candidates per pass over the pixel
      // list (independent histograms, so their increments overlap); the sums of T over the
      // histograms then clear them (see nmi_group_histograms). A short last group repeats its last
      // candidate; the repeats are not stored.
      const std::uint64_t un = static_cast<std::uint64_t>(n);
      const std::uint64_t H_x = detail::entropy_q16(T, un, sum_tx);
      const std::size_t BB = std::size_t(B) * std::size_t(B);
      // Only rows bx_lo .. bx_hi of the joint histograms are touched (a segment's grey values span
      // a few bins): their cells are summed, unless walking the pixels again is shorter.
      const std::size_t row0 = bx_hi >= bx_lo ? std::size_t(bx_lo) * std::size_t(B) : 0;
      const std::size_t touched = bx_hi >= bx_lo ? std::size_t(bx_hi - bx_lo + 1) * std::size_t(B) : 0;
      const bool sum_by_cells = touched <= px.size();
      for (int k0 = 0; k0 < K; k0 += kNmiGroup) {
        const std::uint8_t* bin[kNmiGroup];
        for (int j = 0; j < kNmiGroup; ++j) bin[j] = pr.bin.data() + order[std::size_t(std::min(k0 + j, K - 1))];
        std::uint64_t sum_txy[kNmiGroup], sum_ty[kNmiGroup];
        if (sum_by_cells) {
          // Pass 2 over the touched rows; the partner histograms are their column sums (no
          // per-pixel increments needed).
          nmi_group_histograms<false>(px.data(), px.size(), bin, B, joint.data(), hy.data());
          for (int j = 0; j < kNmiGroup; ++j) {
            std::uint32_t* col = hy.data() + std::size_t(j) * std::size_t(B);
            sum_txy[j] = take_sum_t_rows(joint.data() + std::size_t(j) * BB + row0, bx_hi - bx_lo + 1, B, T.data(), col);
          }
        } else {
          nmi_group_histograms<true>(px.data(), px.size(), bin, B, joint.data(), hy.data());
          take_joint_sums_by_pixels(px.data(), px.size(), bin, B, joint.data(), T.data(), sum_txy);
        }
        for (int j = 0; j < kNmiGroup; ++j)
          sum_ty[j] = take_sum_t(hy.data() + std::size_t(j) * std::size_t(B), std::size_t(B), T.data());
        for (int j = 0; j < kNmiGroup && k0 + j < K; ++j) {
          const int d = order[std::size_t(k0 + j)];
          const std::uint64_t H_y = detail::entropy_q16(T, un, sum_ty[j]);
          const std::uint64_t H_xy = detail::entropy_q16(T, un, sum_txy[j]);
          std::uint32_t nmi = 0;
          const std::uint64_t den = detail::isqrt64(H_x * H_y);  // Q16
          if (den > 0 && H_x + H_y > H_xy) {
            const std::uint64_t qn = ((H_x + H_y - H_xy) << kQ16Shift) / den;
            nmi = static_cast<std::uint32_t>(std::min<std::uint64_t>(qn, kQ16One));
          }
          rec[k0 + j] = {c.ncc[off + std::size_t(d)], c.igsad[off + std::size_t(d)], nmi, d};
        }
      }
    }
  }
}

}  // namespace fs
