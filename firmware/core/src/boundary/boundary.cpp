// Segment-boundary refinement (not in the paper; docs/algorithm.md 4b). The WTA paints one
// disparity per superpixel; where a segment straddles a depth edge its pixels on the far side of
// the edge carry the wrong surface's disparity (foreground fattening). Each pixel is offered the
// disparities painted a few pixels away along its row and column and takes one when its
// windowed census cost is clearly lower than its own segment's.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
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
};

struct Ctx {
  const ImageI16* cur;
  const ImageU32* cref;
  const ImageU32* cother;
  ImageI16* next;
  int direction, r, bits, margin, jump, step;
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

void refine_segment(const Ctx& c, const Segmentation& seg, int s, SegScratch& sc) {
  const ImageI16& cur = *c.cur;
  const std::int32_t rb = seg.run_begin[s], re = seg.run_begin[s + 1];
  if (rb == re) return;
  int x0 = seg.runs[rb].x0, x1 = seg.runs[rb].x1 - 1;
  const int y0 = seg.runs[rb].y, y1 = seg.runs[re - 1].y;
  for (std::int32_t ri = rb; ri < re; ++ri) {
    x0 = std::min(x0, int(seg.runs[ri].x0));
    x1 = std::max(x1, int(seg.runs[ri].x1) - 1);
  }
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
