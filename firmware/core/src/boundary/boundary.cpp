// Segment-boundary refinement (not in the paper; docs/algorithm.md 4b). The WTA paints one
// disparity per superpixel; where a segment straddles a depth edge its pixels on the far side of
// the edge carry the wrong surface's disparity (foreground fattening). Each pixel is offered the
// disparities painted a few pixels away along its row and column and takes one when its
// windowed census cost is clearly lower than its own segment's.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#if defined(__x86_64__)
#include <immintrin.h>
#endif
#if defined(__aarch64__) && defined(__ARM_NEON)
#include <arm_neon.h>
#define FS_HAVE_NEON_COUNT 1
#endif
#include <stdexcept>
#include <string>

#include "fuzzystereo/detect.hpp"
#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {

// One row of the census transform; rows above/below clamped by the caller's pointers.
FS_TARGET_CLONES
void census_row(const std::uint8_t* const* rows, int w, int radius, std::uint32_t* out) {
  const std::uint8_t* c = rows[radius];
  for (int x = 0; x < w; ++x) out[x] = 0;
  int bit = 0;
  for (int dy = 0; dy <= 2 * radius; ++dy) {
    const std::uint8_t* r = rows[dy];
    for (int dx = -radius; dx <= radius; ++dx) {
      if (dx == 0 && dy == radius) continue;
      // Interior columns without clamping (vectorised); the border columns clamp.
      const int lo = std::max(0, -dx), hi = std::min(w, w - dx);
      for (int x = 0; x < std::min(lo, w); ++x) out[x] |= std::uint32_t(r[std::clamp(x + dx, 0, w - 1)] < c[x]) << bit;
      for (int x = lo; x < hi; ++x) out[x] |= std::uint32_t(r[x + dx] < c[x]) << bit;
      for (int x = std::max(hi, 0); x < w; ++x) out[x] |= std::uint32_t(r[std::clamp(x + dx, 0, w - 1)] < c[x]) << bit;
      ++bit;
    }
  }
}

}  // namespace

ImageU32 census_transform(const ImageU8& img, int radius) {
  if (radius < 1 || radius > 2)  // (2r + 1)^2 - 1 bits must fit the 32-bit code (and rows[] below)
    throw std::invalid_argument("census_transform: radius must be 1 or 2, got " + std::to_string(radius));
  const int w = img.width, h = img.height;
  ImageU32 out(w, h, 0);
  if (w == 0 || h == 0) return out;
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* rows[5];
    for (int dy = -radius; dy <= radius; ++dy) rows[dy + radius] = img.row(std::clamp(y + dy, 0, h - 1));
    census_row(rows, w, radius, out.row(y));
  }
  return out;
}

namespace {

using detect::disp_bin;  // round(d) of a Q4 disparity (the v-disparity's bins)

// Per-thread scratch of one segment: the summed-area tables of the disparities its pixels need
// (one per rounded disparity, `slot_of` maps a disparity to its table), built on first use.
struct SegScratch {
  std::vector<int> ds;                // rounded disparity of each table
  std::vector<std::int16_t> slot_of;  // [rounded disparity] -> table index, -1 = none
  std::vector<std::uint32_t> tables;  // ds.size() tables of (H_e + 1) x (W_e + 1), modulo 2^32
  // The lane path's (refine_segment_lanes):
  std::vector<std::int16_t> bins;          // rounded disparity of each table
  std::vector<std::uint16_t> lane_tables;  // bins.size() tables of window sums, bh x (chunks * kLanes)
  std::vector<std::uint16_t> ham;          // the Hamming rows of the table being built
  std::vector<std::uint16_t> vsum;         // their column sums
};

// How the lane path counts the bits of census differences: AVX-512 VPOPCNTDQ, AVX2 nibble lookups,
// NEON byte counts (AArch64), or the portable SWAR count (any CPU). All give the same counts.
enum class CountIsa { kSwar, kAvx2, kVpopcnt, kNeon };

struct Ctx {
  const ImageI16* cur;
  const ImageU32* cref;
  const ImageU32* cother;
  ImageI16* next;
  int direction, r, bits, margin, jump, step;
  CountIsa isa;  // the lane tables' Hamming rows: how this CPU counts bits, decided once per refinement
};

// The candidates of pixel (x, y), in the order of the scalar reference: the map's values at -k, +k
// along the row, -k, +k along the column, then the same at 2k, kept when they differ from d0 by
// >= jump (Q4). The reference also drops a value whose rounded disparity an earlier candidate has;
// here such repeats stay (a repeat has the same cost as the earlier one, and only a strictly lower
// cost replaces the best, so the result is the same — and cheaper than the test).
inline int gather(const std::int16_t* const* rows, int w, int k, int jump, int x, std::int16_t d0, std::int16_t* cand) {
  const std::int16_t* row = rows[2];
  std::int16_t vals[8];
  if (x >= 2 * k && x + 2 * k < w) {  // interior: no clamping
    vals[0] = row[x - k], vals[1] = row[x + k], vals[4] = row[x - 2 * k], vals[5] = row[x + 2 * k];
  } else {
    vals[0] = row[std::max(x - k, 0)], vals[1] = row[std::min(x + k, w - 1)];
    vals[4] = row[std::max(x - 2 * k, 0)], vals[5] = row[std::min(x + 2 * k, w - 1)];
  }
  vals[2] = rows[1][x], vals[3] = rows[3][x], vals[6] = rows[0][x], vals[7] = rows[4][x];
  int nc = 0;
  for (const std::int16_t v : vals) {  // branch-free: the outcomes are data-dependent
    cand[nc] = v;
    nc += (v != kInvalidDisp) & (std::abs(v - d0) >= jump);
  }
  return nc;
}

// Summed-area table over the expanded box [X0, X0 + We) x [Y0, Y0 + He) of the Hamming distance at
// disparity d of the clamped pixel (the window rule of the reference: window pixels outside the
// image take the nearest image pixel; partners outside the other image count `bits`). uint32
// modulo 2^32: a window sum is a difference of four entries, exact while the true sum
// (<= window^2 * 24) is below 2^32, however large the box.
FS_TARGET_CLONES_V3
void build_table(const Ctx& c, int X0, int Y0, int We, int He, int d, std::uint32_t* t) {
  const int w = c.cref->width, h = c.cref->height;
  const int shift = -c.direction * d;
  const int stride = We + 1;
  for (int i = 0; i <= We; ++i) t[i] = 0;
  // Columns i whose pixel X0 + i and its partner are both inside the images: [ia, ib).
  const int ia = std::clamp(std::max(0, -shift) - X0, 0, We);
  const int ib = std::clamp(std::min(w, w - shift) - X0, ia, We);
  for (int j = 0; j < He; ++j) {
    const int y = std::clamp(Y0 + j, 0, h - 1);
    const std::uint32_t* a = c.cref->row(y);
    const std::uint32_t* b = c.cother->row(y);
    const std::uint32_t* up = t + std::size_t(j) * stride + 1;
    std::uint32_t* out = t + std::size_t(j + 1) * stride + 1;
    out[-1] = 0;
    std::uint32_t run = 0;  // the row's running sum; out = the rows above + this row up to column i
    auto clamped = [&](int i) -> std::uint32_t {
      const int x = std::clamp(X0 + i, 0, w - 1), xo = x + shift;
      return (xo < 0 || xo >= w) ? std::uint32_t(c.bits) : std::uint32_t(std::popcount(a[x] ^ b[xo]));
    };
    for (int i = 0; i < ia; ++i) out[i] = up[i] + (run += clamped(i));
    const std::uint32_t* ax = a + X0;
    const std::uint32_t* bx = b + X0 + shift;
    for (int i = ia; i < ib; ++i) out[i] = up[i] + (run += std::uint32_t(std::popcount(ax[i] ^ bx[i])));
    for (int i = ib; i < We; ++i) out[i] = up[i] + (run += clamped(i));
  }
}

// The scalar path (segments near the image's left and right borders): per segment, a summed-area
// table per rounded disparity its pixels need, built on first use, and each pixel's candidates one
// by one.
// Box columns [x0, x1] (refine_segment's).
void refine_segment_scalar(const Ctx& c, const Segmentation& seg, int s, SegScratch& sc, int x0, int x1) {
  const ImageI16& cur = *c.cur;
  const std::int32_t rb = seg.run_begin[s], re = seg.run_begin[s + 1];
  const int y0 = seg.runs[rb].y, y1 = seg.runs[re - 1].y;
  const int r = c.r, n = 2 * r + 1;
  const int X0 = x0 - r, Y0 = y0 - r, We = x1 - x0 + 1 + 2 * r, He = y1 - y0 + 1 + 2 * r;
  const std::size_t stride = std::size_t(We) + 1;
  const std::size_t tsize = std::size_t(He + 1) * stride;
  sc.ds.clear();
  // The table of rounded disparity d, built the first time a pixel of the segment needs it.
  auto table = [&](int d) -> std::size_t {
    std::int16_t& k = sc.slot_of[d];
    if (k < 0) {
      k = static_cast<std::int16_t>(sc.ds.size());
      sc.ds.push_back(d);
      if (sc.tables.size() < sc.ds.size() * tsize) sc.tables.resize(sc.ds.size() * tsize);
      build_table(c, X0, Y0, We, He, d, sc.tables.data() + std::size_t(k) * tsize);
    }
    return std::size_t(k) * tsize;
  };
  for (std::int32_t ri = rb; ri < re; ++ri) {
    const Run& run = seg.runs[ri];
    const std::int16_t* row = cur.row(run.y);
    std::int16_t* out = c.next->row(run.y);
    const int h = cur.height, k = c.step;  // rows y - 2k, y - k, y, y + k, y + 2k (clamped)
    const std::int16_t* rows[5] = {cur.row(std::max(run.y - 2 * k, 0)), cur.row(std::max(run.y - k, 0)), row,
                                   cur.row(std::min(run.y + k, h - 1)), cur.row(std::min(run.y + 2 * k, h - 1))};
    for (int x = run.x0; x < run.x1; ++x) {
      const std::int16_t d0 = row[x];
      if (d0 == kInvalidDisp) continue;
      std::int16_t cand[8];
      const int nc = gather(rows, cur.width, k, c.jump, x, d0, cand);
      if (nc == 0) continue;
      // Window sum centred on (x, y): four reads of a table at the same offsets.
      const std::size_t a = std::size_t(run.y - r - Y0) * stride + std::size_t(x - r - X0), b = a + n;
      const std::size_t cc = a + std::size_t(n) * stride, dd = cc + n;
      auto window = [&](std::size_t off) {
        const std::uint32_t* t = sc.tables.data() + off;
        return static_cast<int>(t[dd] - t[b] - t[cc] + t[a]);  // exact: the true sum < 2^32
      };
      int best = window(table(disp_bin(d0))) - c.margin;  // a candidate must beat this
      std::int16_t best_d = d0;
      for (int j = 0; j < nc; ++j) {
        const int cost = window(table(disp_bin(cand[j])));
        const bool better = cost < best;  // ties keep the earlier candidate
        best = better ? cost : best;
        best_d = better ? cand[j] : best_d;
      }
      out[x] = best_d;
    }
  }
  for (const int d : sc.ds) sc.slot_of[d] = -1;  // reset for the next segment
}

// The lane path: a segment whose box rows, with the candidates' reach 2 step on either side, lie
// inside the image is decided kLanes pixels of a box row at a time, every step a plain loop over
// the lanes (vectorised): the candidates are contiguous loads of the map, and a candidate's cost is
// picked from the segment's tables by comparing its rounded disparity with each table's. The
// result is the scalar path's (and the reference's) bit for bit: the same candidates in the same
// order, the same strict comparison.
constexpr int kLanes = 16;

// The lane helpers below take and return vectors by value; they are always inlined, so the ABI note
// of gcc (-Wpsabi: a vector argument's passing differs between ISA levels) does not concern them.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

// One chunk of lanes as a gcc/clang vector (AVX2 / NEON / SSE2 registers; the code is the same on each).
using U16L = std::uint16_t __attribute__((vector_size(2 * kLanes)));
using I16L = std::int16_t __attribute__((vector_size(2 * kLanes)));
using U32L = std::uint32_t __attribute__((vector_size(4 * kLanes)));
// Half a chunk: the tables' Hamming rows end with one (window <= 9 needs n - 1 <= 8 columns more).
constexpr int kHalf = kLanes / 2;
using U16H = std::uint16_t __attribute__((vector_size(2 * kHalf)));
using U32H = std::uint32_t __attribute__((vector_size(4 * kHalf)));

template <class V, class T>
[[gnu::always_inline]] inline V load(const T* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V, class T>
[[gnu::always_inline]] inline void store(T* p, V v) {
  std::memcpy(p, &v, sizeof v);
}

// Bit counts of 32-bit lanes (SWAR: the same code on every target), narrowed to 16 bits (a census
// code has <= 24 bits).
template <class V32>
[[gnu::always_inline]] inline V32 popcount_swar(V32 x) {
  x = x - ((x >> 1) & 0x55555555u);
  x = (x & 0x33333333u) + ((x >> 2) & 0x33333333u);
  x = (x + (x >> 4)) & 0x0F0F0F0Fu;
  return (x * 0x01010101u) >> 24;
}
[[gnu::always_inline]] inline U16L popcount16(U32L x) { return __builtin_convertvector(popcount_swar(x), U16L); }
[[gnu::always_inline]] inline U16H popcount16(U32H x) { return __builtin_convertvector(popcount_swar(x), U16H); }

// The Hamming rows' whole chunk (kLanes counts of a[i] ^ b[i]) and half chunk (kHalf counts).
[[gnu::always_inline]] inline void count_chunk(std::uint16_t* out, const std::uint32_t* a, const std::uint32_t* b) {
  store(out, popcount16(load<U32L>(a) ^ load<U32L>(b)));
}
[[gnu::always_inline]] inline void count_half(std::uint16_t* out, const std::uint32_t* a, const std::uint32_t* b) {
  store(out, popcount16(load<U32H>(a) ^ load<U32H>(b)));
}

#if defined(FS_HAVE_VPOPCNT_DISPATCH)
// The same with AVX-512 VPOPCNTDQ (inlined only into functions compiled with FS_TARGET_VPOPCNT).
FS_TARGET_VPOPCNT [[gnu::always_inline]] inline U16L popcount16_vpopcnt(U32L x) {
  return __builtin_convertvector(std::bit_cast<U32L>(_mm512_popcnt_epi32(std::bit_cast<__m512i>(x))), U16L);
}
FS_TARGET_VPOPCNT [[gnu::always_inline]] inline U16H popcount16_vpopcnt(U32H x) {
  return __builtin_convertvector(std::bit_cast<U32H>(_mm256_popcnt_epi32(std::bit_cast<__m256i>(x))), U16H);
}
FS_TARGET_VPOPCNT [[gnu::always_inline]] inline void count_chunk_vpopcnt(std::uint16_t* out, const std::uint32_t* a,
                                                                      const std::uint32_t* b) {
  store(out, popcount16_vpopcnt(load<U32L>(a) ^ load<U32L>(b)));
}
FS_TARGET_VPOPCNT [[gnu::always_inline]] inline void count_half_vpopcnt(std::uint16_t* out, const std::uint32_t* a,
                                                                     const std::uint32_t* b) {
  store(out, popcount16_vpopcnt(load<U32H>(a) ^ load<U32H>(b)));
}
#endif

#if defined(FS_HAVE_AVX2_DISPATCH)
// The same with AVX2, which has no vector bit count: each byte's count by two nibble lookups
// (vpshufb into a 16-entry table), summed over the four bytes of a 32-bit lane by two multiply-adds,
// then narrowed to 16 bits (inlined only into functions compiled with FS_TARGET_AVX2_POPCNT): 8
// instructions per register against the SWAR count's 12, whose 32-bit multiply is a slow one.
FS_TARGET_AVX2_POPCNT [[gnu::always_inline]] inline __m256i popcount32_avx2(__m256i x) {
  const __m256i table = _mm256_setr_epi8(0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4,  //
                                         0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4);
  const __m256i nibble = _mm256_set1_epi8(0x0F);
  const __m256i lo = _mm256_and_si256(x, nibble), hi = _mm256_and_si256(_mm256_srli_epi16(x, 4), nibble);
  const __m256i bytes = _mm256_add_epi8(_mm256_shuffle_epi8(table, lo), _mm256_shuffle_epi8(table, hi));
  const __m256i pairs = _mm256_maddubs_epi16(bytes, _mm256_set1_epi8(1));  // bytes 0+1, 2+3 (<= 16)
  return _mm256_madd_epi16(pairs, _mm256_set1_epi16(1));                   // the lane's count (<= 32)
}
// The Hamming rows' whole chunk (kLanes counts of a[i] ^ b[i]) and half chunk, on whole registers
// loaded and stored directly (through the gcc vector types, gcc moved the halves through the stack).
FS_TARGET_AVX2_POPCNT [[gnu::always_inline]] inline void count_chunk_avx2(std::uint16_t* out, const std::uint32_t* a,
                                                                          const std::uint32_t* b) {
  const __m256i* va = reinterpret_cast<const __m256i*>(a);
  const __m256i* vb = reinterpret_cast<const __m256i*>(b);
  const __m256i c0 = popcount32_avx2(_mm256_xor_si256(_mm256_loadu_si256(va), _mm256_loadu_si256(vb)));
  const __m256i c1 = popcount32_avx2(_mm256_xor_si256(_mm256_loadu_si256(va + 1), _mm256_loadu_si256(vb + 1)));
  // packus interleaves the 128-bit halves (c0 lo, c1 lo, c0 hi, c1 hi); the permute restores the order.
  const __m256i packed = _mm256_permute4x64_epi64(_mm256_packus_epi32(c0, c1), 0xD8);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), packed);
}
FS_TARGET_AVX2_POPCNT [[gnu::always_inline]] inline void count_half_avx2(std::uint16_t* out, const std::uint32_t* a,
                                                                         const std::uint32_t* b) {
  const __m256i c = popcount32_avx2(_mm256_xor_si256(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(a)),
                                                     _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b))));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out),
                   _mm_packus_epi32(_mm256_castsi256_si128(c), _mm256_extracti128_si256(c, 1)));
}
#endif

#if defined(FS_HAVE_NEON_COUNT)
// The same on AArch64: NEON counts each byte's bits (CNT); a pairwise widening add gives each 16-bit
// half's count and a pairwise add of two registers each 32-bit lane's, already narrowed and in order
// (the SWAR count needs a dozen instructions and a multiply per register instead).
[[gnu::always_inline]] inline uint16x8_t count8_neon(const std::uint32_t* a, const std::uint32_t* b) {
  const uint16x8_t lo = vpaddlq_u8(vcntq_u8(vreinterpretq_u8_u32(veorq_u32(vld1q_u32(a), vld1q_u32(b)))));
  const uint16x8_t hi = vpaddlq_u8(vcntq_u8(vreinterpretq_u8_u32(veorq_u32(vld1q_u32(a + 4), vld1q_u32(b + 4)))));
  return vpaddq_u16(lo, hi);  // lanes 0-3 from a[0..3], 4-7 from a[4..7]
}
[[gnu::always_inline]] inline void count_chunk_neon(std::uint16_t* out, const std::uint32_t* a, const std::uint32_t* b) {
  vst1q_u16(out, count8_neon(a, b));
  vst1q_u16(out + 8, count8_neon(a + 8, b + 8));
}
[[gnu::always_inline]] inline void count_half_neon(std::uint16_t* out, const std::uint32_t* a, const std::uint32_t* b) {
  vst1q_u16(out, count8_neon(a, b));
}
#endif

struct LaneChunk {
  const std::int16_t* v[9];          // the map at the chunk's pixels (v[0]) and at its 8 candidate places
  const Run* runs;                   // the segment's runs on the chunk's row
  int nruns, x;                      // their count; the chunk's first column
  const std::uint16_t* const* cost;  // each table's window sums (row-major, the chunk's pixels at `off`)
  std::size_t off;
  const std::int16_t* bins;          // each table's rounded disparity
  int tables, jump, margin;
};

// The window sum of each lane at the rounded disparity of v (0 where the segment has no table for
// it) and whether it has one (-1 / 0).
[[gnu::always_inline]] inline void pick_costs(const LaneChunk& ch, I16L v, I16L& cost, I16L& known) {
  const I16L b = (v + I16L{} + kDispScale / 2) >> kDispShift;
  cost = I16L{}, known = I16L{};
  for (int t = 0; t < ch.tables; ++t) {
    const I16L m = b == ch.bins[t];
    cost |= load<I16L>(ch.cost[t] + ch.off) & m;
    known |= m;
  }
}

// Decides the chunk's pixels: out = the chosen disparity of each lane (a pixel without an estimate
// or without a candidate keeps its value; lanes outside the segment are not to be used). Returns false, with `need` (bit j - 1
// for candidate j, bit 8 for the pixel's own disparity) marking the lanes whose table the segment
// does not have yet, when there are such lanes; the caller builds the tables and calls again.
FS_TARGET_CLONES FS_NO_UNROLL_AND_JAM
bool decide_chunk(const LaneChunk& ch, std::int16_t* out, std::int16_t* need) {
  const I16L d0 = load<I16L>(ch.v[0]);
  const I16L invalid = I16L{} + kInvalidDisp;
  I16L c, known;
  pick_costs(ch, d0, c, known);
  const I16L own_known = known;
  I16L best = c - static_cast<std::int16_t>(ch.margin), best_d = d0, any = I16L{}, missing = I16L{};
  I16L lane_x;  // the lanes' columns
  for (int i = 0; i < kLanes; ++i) lane_x[i] = static_cast<std::int16_t>(ch.x + i);
  I16L in_seg = I16L{};  // -1 where the lane's pixel belongs to the segment
  for (int q = 0; q < ch.nruns; ++q)
    in_seg |= (lane_x >= static_cast<std::int16_t>(ch.runs[q].x0)) & (lane_x < static_cast<std::int16_t>(ch.runs[q].x1));
  const I16L valid0 = in_seg & (d0 != invalid);
  const std::int16_t jump = static_cast<std::int16_t>(ch.jump);
  for (int j = 1; j <= 8; ++j) {
    const I16L v = load<I16L>(ch.v[j]);
    pick_costs(ch, v, c, known);
    const I16L diff = v - d0;
    const I16L adiff = diff < 0 ? -diff : diff;
    const I16L ok = valid0 & (v != invalid) & (adiff >= jump);
    const std::int16_t bit = static_cast<std::int16_t>(1 << (j - 1));
    missing |= (ok & ~known) & bit;
    any |= ok;
    const I16L better = ok & (c < best);  // ties keep the earlier candidate
    best = better ? c : best;
    best_d = better ? v : best_d;
  }
  missing |= (any & ~own_known) & static_cast<std::int16_t>(1 << 8);
  store(out, best_d);
  std::int16_t miss = 0;
  for (int i = 0; i < kLanes; ++i) miss = static_cast<std::int16_t>(miss | missing[i]);
  if (!miss) return true;
  store(need, missing);
  return false;
}

// Appends to the segment's list the rounded disparities that `need` (from decide_chunk) marks.
void add_missing_bins(const LaneChunk& ch, const std::int16_t* need, SegScratch& sc, std::vector<std::int16_t>& bins) {
  std::int16_t last[9];  // the value last added per place: neighbouring lanes mostly repeat it
  for (std::int16_t& l : last) l = kInvalidDisp;
  for (int i = 0; i < kLanes; ++i) {
    if (!need[i]) continue;
    for (int j = 0; j <= 8; ++j) {
      if (!(need[i] & (1 << j))) continue;
      const std::int16_t v = ch.v[j == 8 ? 0 : j + 1][i];
      if (v == last[j]) continue;
      last[j] = v;
      const int d = disp_bin(v);
      std::int16_t& k = sc.slot_of[d];
      if (k < 0) {
        k = static_cast<std::int16_t>(sc.ds.size());
        sc.ds.push_back(d);
        bins.push_back(static_cast<std::int16_t>(d));
      }
    }
  }
}

// True when the lane path may run the segment with box columns [x0, x1]: its chunks of kLanes
// columns, the candidates' reach (2 step) and its tables' Hamming rows (from x0 - r to kHalf
// columns past the last chunk) all lie inside the image.
bool lane_path_fits(int x0, int x1, int w, int k, int r) {
  const int chunks = (x1 - x0 + kLanes) / kLanes;
  return x0 - std::max(2 * k, r) >= 0 && x0 + chunks * kLanes + std::max(2 * k, kHalf - r) <= w;
}

// A lane table of rounded disparity d: the window sums at the pixels of a segment's box, `chunks` *
// kLanes columns from x0 (the row stride Wt) and bh rows from y0 — for the box's columns the sums of
// build_table (the rest is read by lanes outside the segment only). Separable and without
// remainder loops: the Hamming rows (below), their running sums over n rows, then sums over n
// columns, each a whole number of chunks and half chunks.
//
// The Hamming rows: He = bh + n - 1 rows of Wh = Wt + kHalf columns from (X0, Y0) = (x0 - r, y0 - r)
// (rows clamped to the image as the reference does, columns inside it by lane_path_fits; a
// partner outside the other image counts `bits`). One variant per bit count (CountIsa), differing only
// in how a whole chunk's and the half chunk's bits are counted.
#define FS_HAMMING_ROWS(NAME, ATTR, COUNT_CHUNK, COUNT_HALF)                                                              \
  ATTR void NAME(const Ctx& c, int X0, int Y0, int chunks, int He, int d, std::uint16_t* ham) {         \
    const int w = c.cref->width, h = c.cref->height;                                                      \
    const int Wt = chunks * kLanes, Wh = Wt + kHalf;                                                      \
    const int shift = -c.direction * d;                                                                   \
    const auto bits = static_cast<std::uint16_t>(c.bits);                                                 \
    for (int j = 0; j < He; ++j) {                                                                        \
      const int y = std::clamp(Y0 + j, 0, h - 1);                                                         \
      const std::uint32_t* a = c.cref->row(y) + X0;                                                       \
      const std::uint32_t* bo = c.cother->row(y);                                                         \
      std::uint16_t* out = ham + std::size_t(j) * Wh;                                                     \
      for (int q = 0; q < chunks; ++q) {                                                                  \
        const int xs = X0 + q * kLanes + shift; /* the partner of the chunk's first column */             \
        if (xs >= 0 && xs + kLanes <= w) {                                                                \
          COUNT_CHUNK(out + q * kLanes, a + q * kLanes, bo + xs);                                         \
        } else {                                                                                          \
          for (int i = 0; i < kLanes; ++i) {                                                              \
            const int xo = xs + i;                                                                        \
            out[q * kLanes + i] = (xo < 0 || xo >= w)                                                     \
                                      ? bits                                                              \
                                      : static_cast<std::uint16_t>(std::popcount(a[q * kLanes + i] ^ bo[xo])); \
          }                                                                                               \
        }                                                                                                 \
      }                                                                                                   \
      const int xt = Wt;                                                                                  \
      const int xs = X0 + xt + shift;                                                                     \
      if (xs >= 0 && xs + kHalf <= w) {                                                                   \
        COUNT_HALF(out + xt, a + xt, bo + xs);                                                            \
      } else {                                                                                            \
        for (int i = 0; i < kHalf; ++i) {                                                                 \
          const int xo = xs + i;                                                                          \
          out[xt + i] = (xo < 0 || xo >= w) ? bits : static_cast<std::uint16_t>(std::popcount(a[xt + i] ^ bo[xo])); \
        }                                                                                                 \
      }                                                                                                   \
    }                                                                                                     \
  }
FS_HAMMING_ROWS(hamming_rows, FS_TARGET_CLONES_V3, count_chunk, count_half)
#if defined(FS_HAVE_AVX2_DISPATCH)
FS_HAMMING_ROWS(hamming_rows_avx2, FS_TARGET_AVX2_POPCNT, count_chunk_avx2, count_half_avx2)
#endif
#if defined(FS_HAVE_NEON_COUNT)
FS_HAMMING_ROWS(hamming_rows_neon, , count_chunk_neon, count_half_neon)
#endif
#if defined(FS_HAVE_VPOPCNT_DISPATCH)
FS_HAMMING_ROWS(hamming_rows_vpopcnt, FS_TARGET_VPOPCNT, count_chunk_vpopcnt, count_half_vpopcnt)
#endif
#undef FS_HAMMING_ROWS

template <int N>
[[gnu::always_inline]] inline void lane_table_impl(const Ctx& c, int x0, int y0, int chunks, int bh, int d,
                                                   std::uint16_t* __restrict ham, std::uint16_t* __restrict vsum,
                                                   std::uint16_t* __restrict t, int n_runtime) {
  const int n = N > 0 ? N : n_runtime;
  const int r = n / 2;
  const int Wh = chunks * kLanes + kHalf;  // Hamming row width (>= chunks * kLanes + n - 1)
#if defined(FS_HAVE_VPOPCNT_DISPATCH)
  if (c.isa == CountIsa::kVpopcnt)
    hamming_rows_vpopcnt(c, x0 - r, y0 - r, chunks, bh + 2 * r, d, ham);
  else
#endif
#if defined(FS_HAVE_AVX2_DISPATCH)
  if (c.isa == CountIsa::kAvx2)
    hamming_rows_avx2(c, x0 - r, y0 - r, chunks, bh + 2 * r, d, ham);
  else
#endif
#if defined(FS_HAVE_NEON_COUNT)
  if (c.isa == CountIsa::kNeon)
    hamming_rows_neon(c, x0 - r, y0 - r, chunks, bh + 2 * r, d, ham);
  else
#endif
    hamming_rows(c, x0 - r, y0 - r, chunks, bh + 2 * r, d, ham);
  // Column sums of n rows, running down the box: whole chunks, then the half chunk.
  auto column_sums = [&]<class V>(int x) {
    V acc = load<V>(ham + x);
    for (int k = 1; k < n; ++k) acc += load<V>(ham + std::size_t(k) * Wh + x);
    store(vsum + x, acc);
    for (int j = 1; j < bh; ++j) {
      acc += load<V>(ham + std::size_t(j - 1 + n) * Wh + x) - load<V>(ham + std::size_t(j - 1) * Wh + x);
      store(vsum + std::size_t(j) * Wh + x, acc);
    }
  };
  for (int q = 0; q < chunks; ++q) column_sums.template operator()<U16L>(q * kLanes);
  column_sums.template operator()<U16H>(chunks * kLanes);
  // Sums of n columns.
  const int Wt = chunks * kLanes;
  for (int j = 0; j < bh; ++j) {
    const std::uint16_t* v = vsum + std::size_t(j) * Wh;
    for (int q = 0; q < chunks; ++q) {
      U16L acc = load<U16L>(v + q * kLanes);
      for (int k = 1; k < n; ++k) acc += load<U16L>(v + q * kLanes + k);
      store(t + std::size_t(j) * Wt + q * kLanes, acc);
    }
  }
}

FS_TARGET_CLONES FS_NO_UNROLL_AND_JAM
void lane_table(const Ctx& c, int x0, int y0, int chunks, int bh, int d, std::uint16_t* ham, std::uint16_t* vsum,
                std::uint16_t* t) {
  const int n = 2 * c.r + 1;
  if (n == 7) return lane_table_impl<7>(c, x0, y0, chunks, bh, d, ham, vsum, t, n);
  if (n == 5) return lane_table_impl<5>(c, x0, y0, chunks, bh, d, ham, vsum, t, n);
  lane_table_impl<0>(c, x0, y0, chunks, bh, d, ham, vsum, t, n);
}

void refine_segment_lanes(const Ctx& c, const Segmentation& seg, int s, SegScratch& sc, int x0, int x1) {
  const ImageI16& cur = *c.cur;
  const std::int32_t rb = seg.run_begin[s], re = seg.run_begin[s + 1];
  const int y0 = seg.runs[rb].y, y1 = seg.runs[re - 1].y;
  const int r = c.r;
  const int bw = x1 - x0 + 1, bh = y1 - y0 + 1;
  const int chunks = (bw + kLanes - 1) / kLanes;
  const int Wt = chunks * kLanes;
  const std::size_t tsize = std::size_t(Wt) * bh;
  const std::size_t hsize = std::size_t(Wt + kHalf) * (bh + 2 * r);
  if (sc.ham.size() < hsize) sc.ham.resize(hsize);
  if (sc.vsum.size() < hsize) sc.vsum.resize(hsize);
  sc.ds.clear();
  std::vector<std::int16_t>& bins = sc.bins;
  bins.clear();
  std::size_t built = 0;
  const int h = cur.height, k = c.step;
  std::int16_t need[kLanes], res[kLanes];
  const std::uint16_t* cost[512];
  std::int32_t ri = rb;
  for (int y = y0; y <= y1; ++y) {
    const std::int32_t r0 = ri;
    while (ri < re && seg.runs[ri].y == y) ++ri;
    if (r0 == ri) continue;
    const std::int16_t* row = cur.row(y);
    const std::int16_t* rows[5] = {cur.row(std::max(y - 2 * k, 0)), cur.row(std::max(y - k, 0)), row,
                                   cur.row(std::min(y + k, h - 1)), cur.row(std::min(y + 2 * k, h - 1))};
    std::int16_t* out = c.next->row(y);
    for (int ch_i = 0; ch_i < chunks; ++ch_i) {
      const int xc = x0 + ch_i * kLanes;
      LaneChunk ch;  // every field set below (no zeroing: this runs per chunk)
      bool any_in = false;
      for (std::int32_t q = r0; q < ri; ++q) any_in |= seg.runs[q].x0 < xc + kLanes && seg.runs[q].x1 > xc;
      if (!any_in) continue;
      ch.runs = seg.runs.data() + r0, ch.nruns = ri - r0, ch.x = xc;
      ch.v[0] = row + xc;
      ch.v[1] = row + xc - k, ch.v[2] = row + xc + k, ch.v[3] = rows[1] + xc, ch.v[4] = rows[3] + xc;
      ch.v[5] = row + xc - 2 * k, ch.v[6] = row + xc + 2 * k, ch.v[7] = rows[0] + xc, ch.v[8] = rows[4] + xc;
      ch.jump = c.jump, ch.margin = c.margin;
      const std::size_t off = std::size_t(y - y0) * Wt + std::size_t(xc - x0);
      for (;;) {
        if (built < bins.size()) {
          if (bins.size() > 512) {  // more neighbours' disparities than the lane path holds: the scalar path
            for (const int d : sc.ds) sc.slot_of[d] = -1;
            return refine_segment_scalar(c, seg, s, sc, x0, x1);
          }
          if (sc.lane_tables.size() < bins.size() * tsize) sc.lane_tables.resize(bins.size() * tsize);
          for (; built < bins.size(); ++built)
            lane_table(c, x0, y0, chunks, bh, bins[built], sc.ham.data(), sc.vsum.data(), sc.lane_tables.data() + built * tsize);
          for (std::size_t t = 0; t < bins.size(); ++t) cost[t] = sc.lane_tables.data() + t * tsize;
        }
        ch.cost = cost, ch.off = off, ch.bins = bins.data(), ch.tables = static_cast<int>(bins.size());
        if (decide_chunk(ch, res, need)) break;
        add_missing_bins(ch, need, sc, bins);
      }
      // The segment's pixels only: a neighbouring segment's (another thread's) are not touched.
      for (std::int32_t q = r0; q < ri; ++q) {
        const int a = std::max(int(seg.runs[q].x0), xc), e = std::min(int(seg.runs[q].x1), xc + kLanes);
        for (int x = a; x < e; ++x) out[x] = res[x - xc];
      }
    }
  }
  for (const int d : sc.ds) sc.slot_of[d] = -1;  // reset for the next segment
}

void refine_segment(const Ctx& c, const Segmentation& seg, int s, SegScratch& sc) {
  const std::int32_t rb = seg.run_begin[s], re = seg.run_begin[s + 1];
  if (rb == re) return;
  int x0 = seg.runs[rb].x0, x1 = seg.runs[rb].x1 - 1;
  for (std::int32_t ri = rb; ri < re; ++ri) {
    x0 = std::min(x0, int(seg.runs[ri].x0));
    x1 = std::max(x1, int(seg.runs[ri].x1) - 1);
  }
  if (lane_path_fits(x0, x1, c.cur->width, c.step, c.r)) return refine_segment_lanes(c, seg, s, sc, x0, x1);
  refine_segment_scalar(c, seg, s, sc, x0, x1);
}

}  // namespace

ImageI16 refine_boundaries(const ImageI16& disp, const Segmentation& seg, const ImageU32& census_ref,
                           const ImageU32& census_other, int direction, const BoundaryParams& p, ImageU8* switched) {
  const int w = disp.width, h = disp.height;
  if (switched) *switched = ImageU8(w, h, 0);
  Ctx c{};
  c.cref = &census_ref, c.cother = &census_other;
  const int side = 2 * p.census_radius + 1;
  c.direction = direction, c.r = p.window / 2, c.bits = side * side - 1;  // a census code's bit count
  c.margin = static_cast<int>(std::lround(p.margin * p.window * p.window));  // [bits per window]
  c.jump = p.min_jump * kDispScale, c.step = p.step;
  c.isa = CountIsa::kSwar;
  if (p.bit_count == BitCount::kAuto) {
#if defined(FS_HAVE_NEON_COUNT)
    c.isa = CountIsa::kNeon;
#endif
#if defined(FS_HAVE_AVX2_DISPATCH)
    if (detail::cpu_has_avx2_popcnt()) c.isa = CountIsa::kAvx2;
#endif
#if defined(FS_HAVE_VPOPCNT_DISPATCH)
    if (__builtin_cpu_supports("avx512vpopcntdq")) c.isa = CountIsa::kVpopcnt;
#endif
  }
  // Tables are indexed by rounded disparity; every candidate is a value of the input map.
  const int bins = detect::disparity_bins(disp);
  ImageI16 out = disp;  // each pass reads the previous one's map and writes a copy of it
  for (int pass = 0; pass < p.passes; ++pass) {
    ImageI16 prev;
    if (pass > 0) prev = out;
    c.cur = pass > 0 ? &prev : &disp, c.next = &out;
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel
#endif
    {
      SegScratch sc;
      sc.slot_of.assign(std::size_t(bins), -1);
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(dynamic, 64)
#endif
      for (int s = 0; s < seg.count; ++s) refine_segment(c, seg, s, sc);
    }
  }
  if (switched)
    for (std::size_t i = 0; i < out.size(); ++i) switched->data[i] = out.data[i] != disp.data[i];
  return out;
}

}  // namespace fs
