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
//
// Sorted kernel (5 x 5 blocks, the default window): per block, sum_c T[c] telescopes over the
// block's bins in sorted order, sum_c T[c] = sum_i dT[p_i] with dT[k] = T[k] - T[k - 1] and p_i the
// position of sample i within its run of equal bins. A compare-exchange network sorts the 25 bins of
// 32 neighbouring blocks at once (uint16 lanes, min / max), a scan gives every p_i, and dT[p_i] is a
// 32-entry table lookup per lane; no branch depends on the data. Same integers as the sliding
// kernel. Builds: AVX-512BW (32 lanes, vpermw) and AVX2 (32 uint8 lanes, vpshufb on byte planes of
// the table), picked at run time, NEON on aarch64 (16 uint8 lanes, tbl), and a portable one (gcc
// vector types; its lookup is scalar code).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

#if defined(FS_HAVE_AVX2_DISPATCH)
#include <immintrin.h>
#endif
#if defined(__aarch64__) && defined(__ARM_NEON)
#include <arm_neon.h>
#define FS_HAVE_NEON_SORTED 1
#endif

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
// bins_row: the histogram bin of each pixel, nearest integer px clamped at dmax, -1 where invalid; as
// int16, or as uint8 for the sorted kernel's byte builds (dmax <= 254: -1 becomes the sentinel 0xFF).
template <typename B>
[[gnu::always_inline]] inline void bins_row_body(const std::int16_t* __restrict d, B* __restrict b, int w, std::int16_t dmax) {
  for (int x = 0; x < w; ++x) {
    const auto v = static_cast<std::int16_t>((d[x] + kDispScale / 2) >> kDispShift);
    b[x] = static_cast<B>(d[x] == kInvalidDisp ? std::int16_t(-1) : std::min(v, dmax));
  }
}
FS_TARGET_CLONES_V4
void bins_row(const std::int16_t* __restrict d, std::int16_t* __restrict b, int w, std::int16_t dmax) {
  bins_row_body(d, b, w, dmax);
}
FS_TARGET_CLONES_V4
void bins_row(const std::int16_t* __restrict d, std::uint8_t* __restrict b, int w, std::int16_t dmax) {
  bins_row_body(d, b, w, dmax);
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
// ---- the sorted kernel (5 x 5 blocks) ----------------------------------------------------------

constexpr int kSortN = 25;      // samples of a 5 x 5 block
constexpr int kSortLanes = 32;  // uint16 lanes of one AVX-512 register: 32 blocks side by side
using SortV = std::uint16_t __attribute__((vector_size(2 * kSortLanes)));
// Invalid pixels and pixels outside the image (the clipped block): sort after every bin (<= 32767)
// and are not counted.
constexpr std::uint16_t kSortSentinel = 0xFFFF;
static_assert(static_cast<std::uint16_t>(std::int16_t{-1}) == kSortSentinel, "bins_row marks an invalid pixel -1");

// The helpers below take and return vectors by value; they are always inlined, so gcc's ABI note
// (-Wpsabi: a vector argument's passing differs between ISA levels) does not concern them.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
// table[idx] per lane (idx < 32): one vpermw with AVX-512BW. clang has no variable __builtin_shuffle.
[[gnu::always_inline]] inline SortV lookup32(SortV table, SortV idx) {
#if defined(__clang__)
  SortV out{};
  for (int i = 0; i < kSortLanes; ++i) out[i] = table[idx[i] & (kSortLanes - 1)];
  return out;
#else
  return __builtin_shuffle(table, idx);
#endif
}

struct CompareExchange {
  std::uint8_t a, b;  // after it, sample a <= sample b
};

// Batcher's odd-even merge sort of 32 inputs (191 compare-exchanges; Knuth, TAOCP 5.3.4, the
// iterative form) with inputs 25..31 held at +infinity: an exchange whose upper input is known to
// be +infinity cannot move anything and is dropped, which leaves 140 that sort 25 samples. (Had an
// exchange a lower +infinity input and a finite upper one it would move the infinity; none has,
// checked below, so the pruned network is exact.)
template <bool kCount>
constexpr int sort25_network(std::array<CompareExchange, 191>* out) {
  constexpr int n = 32;
  bool inf[n] = {};
  for (int i = kSortN; i < n; ++i) inf[i] = true;
  int m = 0;
  for (int p = 1; p < n; p *= 2)
    for (int k = p; k >= 1; k /= 2)
      for (int j = k % p; j + k < n; j += 2 * k)
        for (int i = 0; i < std::min(k, n - j - k); ++i)
          if ((i + j) / (2 * p) == (i + j + k) / (2 * p)) {
            const int a = i + j, b = i + j + k;
            if (inf[b]) continue;
            if (inf[a]) return -1;  // would move an infinity: not expressible as a plain pruning
            if (!kCount) (*out)[std::size_t(m)] = CompareExchange{std::uint8_t(a), std::uint8_t(b)};
            ++m;
          }
  return m;
}
constexpr int kSortCe = sort25_network<true>(nullptr);
static_assert(kSortCe == 140, "the pruned 32-input Batcher network sorts 25 samples in 140 exchanges");
constexpr std::array<CompareExchange, kSortCe> make_sort25() {
  std::array<CompareExchange, 191> all{};
  sort25_network<false>(&all);
  std::array<CompareExchange, kSortCe> net{};
  for (int i = 0; i < kSortCe; ++i) net[std::size_t(i)] = all[std::size_t(i)];
  return net;
}
constexpr std::array<CompareExchange, kSortCe> kSort25 = make_sort25();

struct SortedTables {
  // dT[k] = T[k] - T[k - 1] for k = 1..25 (T: the n*log2 n table, Q16), split as 1024 hi + lo so
  // that 25 terms of either part sum within uint16 (dT[25] < 2^19: hi <= 389, lo <= 1023).
  SortV dt_lo, dt_hi;
  // The same dT as three byte planes, dT = b0 + 256 b1 + 65536 b2 (b2 <= 7; 25 terms of a plane sum
  // within uint16), each plane as two 16-entry vpshufb tables (entries 0..15, 16..31), repeated in
  // both 128-bit halves: the AVX2 build's lookup.
  alignas(32) std::uint8_t plane_a[3][32];
  alignas(32) std::uint8_t plane_b[3][32];
  std::uint32_t t32[kSortN + 1];  // T[n] (< 2^23)
};

// A chunk [x0, x0 + m) of a row with no needed pixel (need_row = nullptr: all are needed) is written as
// 0 and skipped: true when it was.
inline bool skip_unneeded(const std::uint8_t* need_row, int x0, int m, std::int32_t* __restrict o) {
  if (!need_row) return false;
  std::uint8_t any = 0;
  for (int i = 0; i < m; ++i) any |= need_row[x0 + i];
  if (any) return false;
  std::memset(o + x0, 0, sizeof(std::int32_t) * std::size_t(m));
  return true;
}

// The chunk's m entropies e into o[x0 ..], 0 where not needed.
inline void store_chunk(const std::int32_t* e, int m, const std::uint8_t* need_row, int x0, std::int32_t* __restrict o) {
  if (need_row)
    for (int i = 0; i < m; ++i) o[x0 + i] = need_row[x0 + i] ? e[i] : 0;
  else
    std::memcpy(o + x0, e, sizeof(std::int32_t) * std::size_t(m));
}

// eq. (14)'s quotient floor((T[n] - sum + n / 2) / n) for m lanes (the sliding kernel's integers),
// stored where needed. The dividend is < 2^23 and n <= 25, so the double quotient's relative error
// (<= 2^-53) cannot carry it across an integer: its truncation is the exact integer quotient.
[[gnu::always_inline]] inline void store_entropies(const std::uint16_t* nb, const std::uint32_t* sum, int lanes, int m,
                                                   const SortedTables& t, const std::uint8_t* need_row, int x0,
                                                   std::int32_t* __restrict o) {
  std::int32_t e[kSortLanes];
  for (int i = 0; i < lanes; ++i) {
    const std::uint32_t nn = nb[i], sum_t = sum[i], tn = t.t32[nn];
    const std::uint32_t a = tn - sum_t + nn / 2;
    e[i] = nn == 0 || tn <= sum_t ? 0 : static_cast<std::int32_t>(double(a) / double(nn == 0 ? 1 : nn));
  }
  store_chunk(e, m, need_row, x0, o);
}

// The 25 samples of the blocks at columns x0 .. x0 + lanes - 1 (rows: the pad row of the blocks' top
// row; block x covers columns x .. x + 4 of 5 rows), one vector per sample, each lane sorted by the
// network. V: a gcc vector type (or a NEON one) whose lanes are the pad's element type.
template <typename V, typename E>
[[gnu::always_inline]] inline void load_and_sort25(const E* rows, int W, int x0, V* v) {
#pragma GCC unroll 5
  for (int ky = 0; ky < 5; ++ky)
#pragma GCC unroll 5
    for (int kx = 0; kx < 5; ++kx)
      std::memcpy(&v[5 * ky + kx], rows + std::size_t(ky) * std::size_t(W) + std::size_t(x0 + kx), sizeof(V));
#pragma GCC unroll 140
  for (int e = 0; e < kSortCe; ++e) {
    const V a = v[kSort25[std::size_t(e)].a], b = v[kSort25[std::size_t(e)].b];
    v[kSort25[std::size_t(e)].a] = a < b ? a : b;  // vpminuw / vpminub / umin
    v[kSort25[std::size_t(e)].b] = a < b ? b : a;  // vpmaxuw / vpmaxub / umax
  }
}

// Output row y of eq. (14) for 5 x 5 blocks. pad: the bins (kSortSentinel where invalid) with 2
// sentinel rows / columns around the image and kSortLanes more columns on the right, stride W; the
// block of (x, y) is pad rows y..y+4, columns x..x+4.
[[gnu::always_inline]] inline void sorted_entropy_row_body(const std::uint16_t* __restrict pad, int W, int w, int y,
                                                           const SortedTables& t, const std::uint8_t* need_row,
                                                           std::int32_t* __restrict o) {
  const std::uint16_t* rows = pad + std::size_t(y) * std::size_t(W);
  const SortV one = SortV{} + 1, zero = SortV{}, sent = SortV{} + kSortSentinel;
  for (int x0 = 0; x0 < w; x0 += kSortLanes) {
    const int m = std::min(kSortLanes, w - x0);
    if (skip_unneeded(need_row, x0, m, o)) continue;
    SortV v[kSortN];
    load_and_sort25(rows, W, x0, v);
    // p_i: 1 at a run's first sample, +1 along it; dT[p_i] summed over the valid samples.
    SortV pos = one, n = zero, lo = zero, hi = zero;
#pragma GCC unroll 25
    for (int k = 0; k < kSortN; ++k) {
      if (k > 0) pos = v[k] == v[k - 1] ? pos + one : one;
      const auto ok = v[k] != sent;
      n += ok ? one : zero;
      lo += ok ? lookup32(t.dt_lo, pos) : zero;
      hi += ok ? lookup32(t.dt_hi, pos) : zero;
    }
    std::uint16_t nb[kSortLanes], lb[kSortLanes], hb[kSortLanes];
    std::memcpy(nb, &n, sizeof n);
    std::memcpy(lb, &lo, sizeof lo);
    std::memcpy(hb, &hi, sizeof hi);
    std::uint32_t sum[kSortLanes];
    for (int i = 0; i < kSortLanes; ++i) sum[i] = std::uint32_t(hb[i]) * 1024u + lb[i];
    store_entropies(nb, sum, kSortLanes, m, t, need_row, x0, o);
  }
}

// The portable build (gcc lowers the 32-lane table lookup to scalar code: for tests, and for kSorted
// where no other build applies; kAuto takes the sliding kernel there) and the AVX-512BW one.
void sorted_entropy_row(const std::uint16_t* pad, int W, int w, int y, const SortedTables& t, const std::uint8_t* need_row,
                        std::int32_t* o) {
  sorted_entropy_row_body(pad, W, w, y, t, need_row, o);
}
#if defined(FS_HAVE_AVX512BW_DISPATCH)
FS_TARGET_AVX512BW void sorted_entropy_row_avx512(const std::uint16_t* pad, int W, int w, int y, const SortedTables& t,
                                                  const std::uint8_t* need_row, std::int32_t* o) {
  sorted_entropy_row_body(pad, W, w, y, t, need_row, o);
}
#endif

#if defined(FS_HAVE_AVX2_DISPATCH)
// The AVX2 build, for bins <= 254 (max_disparity <= 254): 32 blocks at a time in the uint8 lanes of a
// ymm register (sentinel 0xFF), the same network and run scan, and dT[p_i] by vpshufb from three
// byte planes of the table (SortedTables::plane_a/b). The index byte is p_i (<= 25), | 0x80 for an
// invalid sample; the plane lookup or(pshufb(A, idx +sat 0x70), pshufb(B, idx -sat 0x10)) reads
// A[p] for p < 16 (0x70 + p keeps bit 7 clear), B[p - 16] for p >= 16 and 0 for an invalid sample
// (bit 7 set after either saturating step). Planes 0 and 1 are summed in uint16 (25 * 255 < 2^16),
// plane 2 (<= 7) in uint8 (25 * 7 < 2^8).
using SortV8 = std::uint8_t __attribute__((vector_size(32)));
constexpr int kAvx2Lanes = 32;

// eq. (14)'s quotient for 8 lanes (epi32 n, sum_t): floor((T[n] - sum + n / 2) / n), 0 where n = 0
// or T[n] <= sum; in double as store_entropies (exact for these ranges).
FS_TARGET_AVX2 [[gnu::always_inline]] inline __m256i entropy8(__m256i n, __m256i sum, const std::uint32_t* t32) {
  const __m256i tn = _mm256_i32gather_epi32(reinterpret_cast<const int*>(t32), n, 4);
  const __m256i a = _mm256_add_epi32(_mm256_sub_epi32(tn, sum), _mm256_srli_epi32(n, 1));
  const __m256i nz = _mm256_max_epi32(n, _mm256_set1_epi32(1));
  const __m256d q0 = _mm256_div_pd(_mm256_cvtepi32_pd(_mm256_castsi256_si128(a)), _mm256_cvtepi32_pd(_mm256_castsi256_si128(nz)));
  const __m256d q1 = _mm256_div_pd(_mm256_cvtepi32_pd(_mm256_extracti128_si256(a, 1)),
                                   _mm256_cvtepi32_pd(_mm256_extracti128_si256(nz, 1)));
  const __m256i q = _mm256_set_m128i(_mm256_cvttpd_epi32(q1), _mm256_cvttpd_epi32(q0));
  // zero where n == 0 or T[n] <= sum (T[n] < 2^23 and sum < 2^23: signed compares are exact)
  const __m256i keep = _mm256_andnot_si256(_mm256_cmpeq_epi32(n, _mm256_setzero_si256()), _mm256_cmpgt_epi32(tn, sum));
  return _mm256_and_si256(q, keep);
}

FS_TARGET_AVX2 void sorted_entropy_row_avx2(const std::uint8_t* __restrict pad, int W, int w, int y,
                                            const SortedTables& t, const std::uint8_t* need_row,
                                            std::int32_t* __restrict o) {
  const std::uint8_t* rows = pad + std::size_t(y) * std::size_t(W);
  __m256i ta[3], tb[3];
  for (int j = 0; j < 3; ++j) {
    ta[j] = _mm256_load_si256(reinterpret_cast<const __m256i*>(t.plane_a[j]));
    tb[j] = _mm256_load_si256(reinterpret_cast<const __m256i*>(t.plane_b[j]));
  }
  const SortV8 one = SortV8{} + 1, sent = SortV8{} + 0xFF, invalid_bit = SortV8{} + 0x80;
  const __m256i up = _mm256_set1_epi8(0x70), down = _mm256_set1_epi8(0x10), zero = _mm256_setzero_si256();
  for (int x0 = 0; x0 < w; x0 += kAvx2Lanes) {
    const int m = std::min(kAvx2Lanes, w - x0);
    if (skip_unneeded(need_row, x0, m, o)) continue;
    SortV8 v[kSortN];
    load_and_sort25(rows, W, x0, v);
    SortV8 pos = one, valid = SortV8{}, s2 = SortV8{};
    __m256i s0l = zero, s0h = zero, s1l = zero, s1h = zero;  // uint16: blocks 0-7 | 16-23, 8-15 | 24-31
#pragma GCC unroll 25
    for (int k = 0; k < kSortN; ++k) {
      if (k > 0) pos = (pos & reinterpret_cast<SortV8>(v[k] == v[k - 1])) + one;
      const auto bad = reinterpret_cast<SortV8>(v[k] == sent);  // all ones where invalid
      valid += one + bad;                                     // + 1 where valid, + 0 where not
      const auto idx = reinterpret_cast<__m256i>(pos | (bad & invalid_bit));
      const __m256i ia = _mm256_adds_epu8(idx, up), ib = _mm256_subs_epi8(idx, down);
      const __m256i r0 = _mm256_or_si256(_mm256_shuffle_epi8(ta[0], ia), _mm256_shuffle_epi8(tb[0], ib));
      const __m256i r1 = _mm256_or_si256(_mm256_shuffle_epi8(ta[1], ia), _mm256_shuffle_epi8(tb[1], ib));
      const __m256i r2 = _mm256_or_si256(_mm256_shuffle_epi8(ta[2], ia), _mm256_shuffle_epi8(tb[2], ib));
      s0l = _mm256_add_epi16(s0l, _mm256_unpacklo_epi8(r0, zero));
      s0h = _mm256_add_epi16(s0h, _mm256_unpackhi_epi8(r0, zero));
      s1l = _mm256_add_epi16(s1l, _mm256_unpacklo_epi8(r1, zero));
      s1h = _mm256_add_epi16(s1h, _mm256_unpackhi_epi8(r1, zero));
      s2 += reinterpret_cast<SortV8>(r2);
    }
    // Blocks 8g .. 8g + 7 as epi32: the uint16 sums sit in 128-bit half g / 2 of s*l (g even) or s*h (g odd).
    const auto n8 = reinterpret_cast<__m256i>(valid), p2 = reinterpret_cast<__m256i>(s2);
    alignas(32) std::int32_t e[kAvx2Lanes];
    for (int g = 0; g < 4; ++g) {
      const __m256i s0 = (g & 1) ? s0h : s0l, s1 = (g & 1) ? s1h : s1l;
      const __m128i h0 = g < 2 ? _mm256_castsi256_si128(s0) : _mm256_extracti128_si256(s0, 1);
      const __m128i h1 = g < 2 ? _mm256_castsi256_si128(s1) : _mm256_extracti128_si256(s1, 1);
      const __m128i nb = g < 2 ? _mm256_castsi256_si128(n8) : _mm256_extracti128_si256(n8, 1);
      const __m128i pb = g < 2 ? _mm256_castsi256_si128(p2) : _mm256_extracti128_si256(p2, 1);
      const __m128i nb8 = (g & 1) ? _mm_srli_si128(nb, 8) : nb, pb8 = (g & 1) ? _mm_srli_si128(pb, 8) : pb;
      const __m256i sum = _mm256_add_epi32(
          _mm256_add_epi32(_mm256_cvtepu16_epi32(h0), _mm256_slli_epi32(_mm256_cvtepu16_epi32(h1), 8)),
          _mm256_slli_epi32(_mm256_cvtepu8_epi32(pb8), 16));
      _mm256_store_si256(reinterpret_cast<__m256i*>(e + 8 * g), entropy8(_mm256_cvtepu8_epi32(nb8), sum, t.t32));
    }
    store_chunk(e, m, need_row, x0, o);
  }
}
#endif

#if defined(FS_HAVE_NEON_SORTED)
// The NEON build (aarch64), for bins <= 254 like the AVX2 one: 16 blocks at a time in the uint8 lanes
// of a q register (32 of them: the 25 samples need no spill), the same network and run scan, and
// dT[p_i] by one tbl per byte plane (vqtbl2q_u8 on entries 0-31; an index >= 32 reads 0, so an invalid
// sample's index p_i | 0x80 reads 0). Planes 0 and 1 are summed in uint16 (uaddw), plane 2 in uint8.
constexpr int kNeonLanes = 16;

void sorted_entropy_row_neon(const std::uint8_t* __restrict pad, int W, int w, int y, const SortedTables& t,
                             const std::uint8_t* need_row, std::int32_t* __restrict o) {
  const std::uint8_t* rows = pad + std::size_t(y) * std::size_t(W);
  uint8x16x2_t tab[3];
  for (int j = 0; j < 3; ++j) {
    tab[j].val[0] = vld1q_u8(t.plane_a[j]);  // entries 0-15 (the first 16 bytes of the 32)
    tab[j].val[1] = vld1q_u8(t.plane_b[j]);  // entries 16-31
  }
  const uint8x16_t one = vdupq_n_u8(1), sent = vdupq_n_u8(0xFF), invalid_bit = vdupq_n_u8(0x80);
  for (int x0 = 0; x0 < w; x0 += kNeonLanes) {
    const int m = std::min(kNeonLanes, w - x0);
    if (skip_unneeded(need_row, x0, m, o)) continue;
    uint8x16_t v[kSortN];
    load_and_sort25(rows, W, x0, v);
    uint8x16_t pos = one, valid = vdupq_n_u8(0), s2 = vdupq_n_u8(0);
    uint16x8_t s0l = vdupq_n_u16(0), s0h = s0l, s1l = s0l, s1h = s0l;
#pragma GCC unroll 25
    for (int k = 0; k < kSortN; ++k) {
      if (k > 0) pos = vaddq_u8(vandq_u8(pos, vceqq_u8(v[k], v[k - 1])), one);
      const uint8x16_t bad = vceqq_u8(v[k], sent);  // all ones where invalid
      valid = vaddq_u8(valid, vaddq_u8(one, bad));   // + 1 where valid, + 0 where not
      const uint8x16_t idx = vorrq_u8(pos, vandq_u8(bad, invalid_bit));
      const uint8x16_t r0 = vqtbl2q_u8(tab[0], idx), r1 = vqtbl2q_u8(tab[1], idx), r2 = vqtbl2q_u8(tab[2], idx);
      s0l = vaddw_u8(s0l, vget_low_u8(r0));
      s0h = vaddw_high_u8(s0h, r0);
      s1l = vaddw_u8(s1l, vget_low_u8(r1));
      s1h = vaddw_high_u8(s1h, r1);
      s2 = vaddq_u8(s2, r2);
    }
    std::uint8_t n8[kNeonLanes], p2[kNeonLanes];
    std::uint16_t b0[kNeonLanes], b1[kNeonLanes], nb[kNeonLanes];
    vst1q_u8(n8, valid);
    vst1q_u8(p2, s2);
    vst1q_u16(b0, s0l);
    vst1q_u16(b0 + 8, s0h);
    vst1q_u16(b1, s1l);
    vst1q_u16(b1 + 8, s1h);
    std::uint32_t sum[kNeonLanes];
    for (int i = 0; i < kNeonLanes; ++i) {
      nb[i] = n8[i];
      sum[i] = std::uint32_t(b0[i]) + (std::uint32_t(b1[i]) << 8) + (std::uint32_t(p2[i]) << 16);
    }
    store_entropies(nb, sum, kNeonLanes, m, t, need_row, x0, o);
  }
}
#endif

// The builds of the sorted kernel, fastest first; the best one the CPU runs is taken unless the
// portable one is asked for (tests).
enum class SortedIsa { kAvx512bw, kAvx2, kNeon, kPortable };

// The AVX2 and NEON builds work on uint8 bins: bins 0 .. max_disparity <= 254 (0xFF: the sentinel).
constexpr int kByteMaxBin = 254;

SortedIsa best_sorted_isa(int max_disparity) {
  if (detail::cpu_has_avx512bw()) return SortedIsa::kAvx512bw;
  if (detail::cpu_has_avx2() && max_disparity <= kByteMaxBin) return SortedIsa::kAvx2;
#if defined(FS_HAVE_NEON_SORTED)
  if (max_disparity <= kByteMaxBin) return SortedIsa::kNeon;
#endif
  return SortedIsa::kPortable;
}

ImageI32 block_entropy_sorted(const ImageI16& disp, int max_disparity, const ImageU8* need, SortedIsa isa) {
  const int w = disp.width, h = disp.height, r = 2;
  const int W = w + 2 * r + kSortLanes, H = h + 2 * r;
  // The bins with sentinel borders: uint16 (kSortSentinel), or uint8 (0xFF) for the AVX2 and NEON builds.
  const bool bytes = isa == SortedIsa::kAvx2 || isa == SortedIsa::kNeon;
  std::vector<std::uint16_t> pad(bytes ? 0 : std::size_t(W) * std::size_t(H), kSortSentinel);
  std::vector<std::uint8_t> pad8(bytes ? std::size_t(W) * std::size_t(H) : 0, 0xFF);
  const auto dmax = static_cast<std::int16_t>(std::clamp(max_disparity, 0, 32766));
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    // the sliding kernel's bins; its -1 for an invalid pixel is kSortSentinel as uint16, 0xFF as uint8
    if (bytes)
      bins_row(disp.row(y), pad8.data() + std::size_t(y + r) * std::size_t(W) + r, w, dmax);  // dmax <= 254
    else
      bins_row(disp.row(y), reinterpret_cast<std::int16_t*>(pad.data() + std::size_t(y + r) * std::size_t(W) + r), w, dmax);
  }
  SortedTables t{};
  const std::vector<std::uint64_t> T = detail::nlogn_table_q16(kSortN);
  for (int k = 0; k <= kSortN; ++k) {
    t.t32[k] = static_cast<std::uint32_t>(T[std::size_t(k)]);
    const std::uint64_t dt = k >= 1 ? T[std::size_t(k)] - T[std::size_t(k - 1)] : 0;
    t.dt_lo[k] = static_cast<std::uint16_t>(dt & 1023);
    t.dt_hi[k] = static_cast<std::uint16_t>(dt >> 10);
    for (int j = 0; j < 3; ++j) {
      const auto b = static_cast<std::uint8_t>(dt >> (8 * j));  // dT[25] < 2^19: the planes hold it whole
      std::uint8_t(&plane)[32] = k < 16 ? t.plane_a[j] : t.plane_b[j];
      plane[k % 16] = plane[k % 16 + 16] = b;
    }
  }
  ImageI32 out(w, h, 0);
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* nr = need ? need->row(y) : nullptr;
#if defined(FS_HAVE_AVX512BW_DISPATCH)
    if (isa == SortedIsa::kAvx512bw) {
      sorted_entropy_row_avx512(pad.data(), W, w, y, t, nr, out.row(y));
      continue;
    }
#endif
#if defined(FS_HAVE_AVX2_DISPATCH)
    if (isa == SortedIsa::kAvx2) {
      sorted_entropy_row_avx2(pad8.data(), W, w, y, t, nr, out.row(y));
      continue;
    }
#endif
#if defined(FS_HAVE_NEON_SORTED)
    if (isa == SortedIsa::kNeon) {
      sorted_entropy_row_neon(pad8.data(), W, w, y, t, nr, out.row(y));
      continue;
    }
#endif
    sorted_entropy_row(pad.data(), W, w, y, t, nr, out.row(y));
  }
  return out;
}
}  // namespace

ImageI32 block_entropy(const ImageI16& disp, int window, int max_disparity, const ImageU8* need, EntropyKernel kernel) {
  if (window == 5 && kernel != EntropyKernel::kSliding) {
    const SortedIsa isa = kernel == EntropyKernel::kSortedPortable ? SortedIsa::kPortable : best_sorted_isa(max_disparity);
    // kAuto: only where the sorted kernel was measured faster (the x86-64 builds)
    if (kernel != EntropyKernel::kAuto || isa == SortedIsa::kAvx512bw || isa == SortedIsa::kAvx2)
      return block_entropy_sorted(disp, max_disparity, need, isa);
  }
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

// The rounded mean (2 s + n) / (2 n) of block_mean for one output row, from the row's column sums
// (cs, cn: the block's rows summed per column, with r zero columns on either side). The block sum is
// a sum of `window` shifted column sums (vectorises; no running sum along the row), and the quotient is
// taken in double: the dividend is < 2^31 and the divisor 2 n <= 2 * 99^2, so the quotient's error
// (< 2^31 * 2^-53 = 2^-22) is below its distance to the next integer when inexact (>= 1 / (2 n) >
// 2^-15): its truncation is the exact integer quotient.
// kWin > 0: the window as a constant (the loop over x vectorises); 0: any window (`window`).
template <int kWin, typename Out>
[[gnu::always_inline]] inline void mean_row_body(const std::int32_t* __restrict cs, const std::int32_t* __restrict cn,
                                                 int w, int window, Out* __restrict o) {
  const int win = kWin > 0 ? kWin : window;
  for (int x = 0; x < w; ++x) {
    std::int32_t s = 0, n = 0;
    for (int k = 0; k < win; ++k) {
      s += cs[x + k];
      n += cn[x + k];
    }
    const double q = double(2 * s + n) / double(n > 0 ? 2 * n : 1);
    o[x] = n > 0 ? static_cast<Out>(q) : Out{kInvalidDisp};
  }
}
template <typename Out>
[[gnu::always_inline]] inline void mean_row_dispatch(const std::int32_t* cs, const std::int32_t* cn, int w, int window,
                                                     Out* o) {
  switch (window) {
    case 3: mean_row_body<3>(cs, cn, w, window, o); break;
    case 5: mean_row_body<5>(cs, cn, w, window, o); break;
    case 7: mean_row_body<7>(cs, cn, w, window, o); break;
    case 9: mean_row_body<9>(cs, cn, w, window, o); break;
    default: mean_row_body<0>(cs, cn, w, window, o); break;
  }
}
FS_TARGET_CLONES_V4
void mean_row(const std::int32_t* cs, const std::int32_t* cn, int w, int window, std::int16_t* o) {
  mean_row_dispatch(cs, cn, w, window, o);
}
// The same means as int32 (ESR reads them through 32-bit gathers; there is no 16-bit gather).
FS_TARGET_CLONES_V4
void mean_row(const std::int32_t* cs, const std::int32_t* cn, int w, int window, std::int32_t* o) {
  mean_row_dispatch(cs, cn, w, window, o);
}

// Mean of the valid disparities (Q4) in the clipped w x w block, rounded to nearest; kInvalidDisp
// when the block has no valid pixel. Separable: per output row, the column sums of the block's rows
// (sum, count; running down the rows), then mean_row. int32 is exact: a block holds at most w^2 <= 99^2
// values <= 32767 (< 2^29).
namespace {
template <typename Out>
Image<Out> block_mean_as(const ImageI16& disp, int window) {
  const int w = disp.width, h = disp.height, r = window / 2;
  Image<Out> out(w, h, Out{kInvalidDisp});
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel
#endif
  {
    // r zero columns on either side: the clipped block's missing columns add nothing
    std::vector<std::int32_t> csv(std::size_t(w + 2 * r), 0), cnv(std::size_t(w + 2 * r), 0);
    std::int32_t* cs = csv.data() + r;
    std::int32_t* cn = cnv.data() + r;
    int have0 = 0, have1 = -1;  // rows [have0, have1] are in the column sums
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(static)
#endif
    for (int y = 0; y < h; ++y) {
      const int y0 = std::max(0, y - r), y1 = std::min(h - 1, y + r);
      if (y0 > have1 || y1 < have0 || y0 < have0) {  // first row of this thread's chunk: rebuild
        std::fill(csv.begin(), csv.end(), 0);
        std::fill(cnv.begin(), cnv.end(), 0);
        have0 = y0;
        have1 = y0 - 1;
      }
      for (; have0 < y0; ++have0) {  // rows leaving the block
        const std::int16_t* d = disp.row(have0);
        for (int x = 0; x < w; ++x) {
          const std::int32_t v = d[x], ok = v != kInvalidDisp;
          cs[x] -= ok ? v : 0;
          cn[x] -= ok;
        }
      }
      for (; have1 < y1;) {  // rows entering the block
        const std::int16_t* d = disp.row(++have1);
        for (int x = 0; x < w; ++x) {
          const std::int32_t v = d[x], ok = v != kInvalidDisp;
          cs[x] += ok ? v : 0;
          cn[x] += ok;
        }
      }
      mean_row(cs - r, cn - r, w, window, out.row(y));
    }
  }
  return out;
}
}  // namespace

ImageI16 block_mean(const ImageI16& disp, int window) { return block_mean_as<std::int16_t>(disp, window); }

// eq. (15) for one row: a needed left pixel (valid, partner x - d inside the image) whose block
// entropy differs from its partner's by more than tau takes the block mean of the lower-entropy side,
// when that block has a valid pixel. Branch-free (the partner's entropy and mean are gathers), so it
// vectorises; the partner index is clamped into the row for the pixels that are not needed.
FS_TARGET_CLONES_V4
void esr_row(const std::int16_t* __restrict d, const std::uint8_t* __restrict need, const std::int32_t* __restrict el,
             const std::int32_t* __restrict er, const std::int32_t* __restrict ml, const std::int32_t* __restrict mr,
             int w, std::int64_t tau, std::int16_t* __restrict out, std::uint8_t* __restrict rep) {
  const auto tau32 = static_cast<std::int32_t>(std::min<std::int64_t>(tau, std::int64_t(1) << 30));
  constexpr int kChunk = 256;
  std::int32_t idx[kChunk];  // the partners of a chunk first: gathers through an index array vectorise
  for (int x0 = 0; x0 < w; x0 += kChunk) {
    const int m = std::min(kChunk, w - x0);
    for (int i = 0; i < m; ++i) {
      const int xp = partner_x(x0 + i, d[x0 + i]);
      idx[i] = std::min(std::max(xp, 0), w - 1);
    }
    for (int i = 0; i < m; ++i) {
      const int x = x0 + i, xr = idx[i];
      const std::int32_t a = el[x], b = er[xr];
      const std::int32_t mlx = ml[x], mrx = mr[xr];  // every load unconditional: the loop if-converts
      const std::int32_t diff = a > b ? a - b : b - a;  // entropies are in [0, log2(w^2)] Q16: no overflow
      const std::int32_t mean = a < b ? mlx : mrx;
      const bool take = (need[x] != 0) & (diff > tau32) & (mean != kInvalidDisp);
      out[x] = take ? static_cast<std::int16_t>(mean) : d[x];
      rep[x] = take ? 1 : 0;
    }
  }
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
  ImageI32 Ml, Mr;
  detail::run_pair(
      0, [&] { El = block_entropy(disp_lr, p.window, max_disparity, &need_l, p.kernel); Ml = block_mean_as<std::int32_t>(disp_lr, p.window); },
      [&] { Er = block_entropy(disp_right, p.window, max_disparity, &need_r, p.kernel); Mr = block_mean_as<std::int32_t>(disp_right, p.window); });
  const auto tau = static_cast<std::int64_t>(std::llround(p.tau * kQ16One));
  ImageI16 out(w, h);
  ImageU8 rep_scratch;
  ImageU8& rep = replaced ? *replaced : rep_scratch;
  rep = ImageU8(w, h, 0);
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y)
    esr_row(disp_lr.row(y), need_l.row(y), El.row(y), Er.row(y), Ml.row(y), Mr.row(y), w, tau, out.row(y), rep.row(y));
  return out;
}

}  // namespace fs
