// Superpixel segmentation (Section III, ref. [57]): integer SLIC on grey level and position.
// Each segment is a variable-size matching window for the data costs.
//
// Distance (SLIC, Achanta et al. 2012) scaled by S^2 to stay integer:
//   D' = dI^2 * S^2 + (dx^2 + dy^2) * m^2      (uint32: dI <= 255, |dx|,|dy| <= S, S <= 48,
//                                              m <= 100 -> D' <= 1.5e8 + 4.6e7 < 2^28)
// Iteration tag: the best distance per pixel is kept as tag << 28 | D' (D' < 2^28 by the bound above),
// the tag one lower each iteration, so every distance of an earlier iteration compares larger than any
// of this one — what refilling the distances with UINT32_MAX before each iteration did, without the
// pass over the image (16 iterations per fill). Stored biased (tagged D' ^ 2^31 as int32), so the
// comparisons are signed ones (assign_window).
// Centres: grid of step S, then moved to the lowest-gradient pixel of their 3x3 neighbourhood.
// Coarse start (coarse_iterations > 0, docs/algorithm.md 1): the first rounds on the image halved
// (2 x 2 block means, step S/2), the centres then scaled back to full resolution.
// Centre update: integer mean (rounded) of the assigned pixels' position and grey level.
// Connectivity: pieces smaller than min_segment_pct % of S^2 join the previous neighbouring segment.
#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {

struct Center {
  std::int64_t x, y, i;
};

// Width of the assignment's blocks: 8 uint32 lanes, one AVX2 register (two SSE / NEON ones).
constexpr int kLanes = 8;

// kLanes-wide vectors (GCC vector extensions: one AVX2 register in the avx2 clone, two SSE registers
// in the default one, two NEON registers on the robot).
using U8xL = std::uint8_t __attribute__((vector_size(kLanes)));
using I32xL = std::int32_t __attribute__((vector_size(4 * kLanes)));
using U32xL = std::uint32_t __attribute__((vector_size(4 * kLanes)));

// Distances are stored biased, D ^ 2^31 read as int32 (kBias): the unsigned order of D is the signed
// order of the biased value, so the comparisons are single signed-compare instructions (SSE/AVX2 have
// no unsigned one).
constexpr std::uint32_t kBias = 0x80000000u;

// One centre's search window, for windows narrower than 2 kLanes columns (S < 8: the coarse rounds'
// 9 px): rows [y0, y1], columns x0 .. x0 + nb * kLanes - 1 of the padded planes (row stride `stride`);
// keep the closer centre per pixel (branch-free, SIMD; one call per window so the clone dispatch and
// loop set-up are paid once per centre). The window [x0, x1] is rounded up to whole blocks, so a row
// is nb full vectors with no scalar tail (a 9-pixel row was one 16-lane int16 vector's worth of set-up
// and a scalar loop); the columns past x1 read INT32_MAX (UINT32_MAX biased) from the padded spatial
// table (past the window) or lie in the planes' padding (past the image), and D = max(t^2 + sp, sp)
// keeps such a pixel at INT32_MAX, never closer: the result is that of the window alone. The spatial
// term (dx^2 + dy^2) * m^2 (+ the iteration tag) is read from `spatial`, the table of every offset from
// a centre (the same for all centres: their positions are integers).
FS_TARGET_CLONES
void assign_window(const std::uint8_t* __restrict img, std::int32_t* __restrict dist, std::int32_t* __restrict labels,
                   std::size_t stride, int x0, int nb, int y0, int y1, std::int32_t ci, std::int32_t cx, std::int32_t cy,
                   const std::int32_t* __restrict spatial, std::size_t spatial_stride, int S, std::int32_t k) {
  for (int y = y0; y <= y1; ++y) {
    const std::size_t o = std::size_t(y) * stride + std::size_t(x0);
    const std::uint8_t* __restrict r = img + o;
    std::int32_t* __restrict dr = dist + o;
    std::int32_t* __restrict lab = labels + o;
    // sp[x] = ((dx^2 + dy^2) * m^2 + tag) ^ kBias for dx = x0 + x - cx (x0 >= cx - S); INT32_MAX past 2S
    const std::int32_t* __restrict sp = spatial + std::size_t(y - cy + S) * spatial_stride + std::size_t(x0 - cx + S);
    for (int v = 0; v < nb; ++v) {
      const std::size_t x = std::size_t(v) * kLanes;
      U8xL pix;
      I32xL s, dold, lold;
      std::memcpy(&pix, r + x, sizeof pix);
      std::memcpy(&s, sp + x, sizeof s);
      std::memcpy(&dold, dr + x, sizeof dold);
      std::memcpy(&lold, lab + x, sizeof lold);
      // dI * S (|dI| <= 255, S <= 48: <= 12240) squared: dI^2 S^2 <= 1.5e8, exact in int32
      const I32xL t = (__builtin_convertvector(pix, I32xL) - ci) * S;
      // (t^2 + D_spatial) ^ kBias = t^2 + (D_spatial ^ kBias) mod 2^32 (no carry out of the unbiased sum,
      // < 2^32 for a window pixel: header); a column past the window (sp = INT32_MAX) wraps below
      // INT32_MAX and the max brings it back: never closer.
      const I32xL sum = reinterpret_cast<I32xL>(reinterpret_cast<U32xL>(t * t) + reinterpret_cast<U32xL>(s));
      const I32xL d = sum < s ? s : sum;
      const auto closer = d < dold;  // lanes of -1 (true) / 0
      const I32xL dnew = closer ? d : dold;
      const I32xL lnew = closer ? I32xL{} + k : lold;
      std::memcpy(dr + x, &dnew, sizeof dnew);
      std::memcpy(lab + x, &lnew, sizeof lnew);
    }
  }
}

// The same for windows of >= 2 kLanes columns (S >= 8, the default): the exact width, a plain loop the
// compiler vectorises in 16 int16 lanes ((dI * S) in int16, its square by a 16 x 16 -> 32-bit multiply,
// one vpmaddwd-class instruction) with a short scalar tail — for a 17-pixel row cheaper than three
// rounded-up blocks. Same biased distances and result as assign_window.
FS_TARGET_CLONES
void assign_window_wide(const std::uint8_t* __restrict img, std::int32_t* __restrict dist, std::int32_t* __restrict labels,
                        std::size_t stride, int x0, int x1, int y0, int y1, std::int32_t ci, std::int32_t cx, std::int32_t cy,
                        const std::int32_t* __restrict spatial, std::size_t spatial_stride, int S, std::int32_t k) {
  const auto ci16 = static_cast<std::int16_t>(ci), s16 = static_cast<std::int16_t>(S);
  const int n = x1 - x0 + 1;
  for (int y = y0; y <= y1; ++y) {
    const std::size_t o = std::size_t(y) * stride + std::size_t(x0);
    const std::uint8_t* __restrict r = img + o;
    std::int32_t* __restrict dr = dist + o;
    std::int32_t* __restrict lab = labels + o;
    const std::int32_t* __restrict sp = spatial + std::size_t(y - cy + S) * spatial_stride + std::size_t(x0 - cx + S);
    for (int x = 0; x < n; ++x) {
      const auto t = static_cast<std::int16_t>(static_cast<std::int16_t>(r[x] - ci16) * s16);
      const auto d = static_cast<std::int32_t>(static_cast<std::uint32_t>(std::int32_t(t) * std::int32_t(t)) +
                                               static_cast<std::uint32_t>(sp[x]));  // biased, see assign_window
      const bool closer = d < dr[x];
      dr[x] = closer ? d : dr[x];
      lab[x] = closer ? k : lab[x];
    }
  }
}

// The per-segment fields of a Segmentation from its runs in row-major order and each run's label
// (0 .. count-1): pixel counts, and the runs grouped by segment (a stable counting sort, so each
// segment's runs stay row-major).
void group_runs(Segmentation& seg, int count, const std::vector<Run>& runs, const std::vector<std::int32_t>& label) {
  seg.count = count;
  seg.pixels.assign(std::size_t(count), 0);
  seg.run_begin.assign(std::size_t(count) + 1, 0);
  for (std::size_t i = 0; i < runs.size(); ++i) {
    seg.pixels[std::size_t(label[i])] += runs[i].x1 - runs[i].x0;
    ++seg.run_begin[std::size_t(label[i]) + 1];
  }
  for (int s = 0; s < count; ++s) seg.run_begin[std::size_t(s) + 1] += seg.run_begin[std::size_t(s)];
  seg.runs.resize(runs.size());
  std::vector<std::int32_t> fill(seg.run_begin.begin(), seg.run_begin.end() - 1);
  for (std::size_t i = 0; i < runs.size(); ++i) seg.runs[std::size_t(fill[std::size_t(label[i])]++)] = runs[i];
}

// The image halved in both directions: each pixel the rounded mean of a 2 x 2 block (the last
// column / row of an odd size repeats).
ImageU8 halve(const ImageU8& img) {
  const int w = img.width, h = img.height, hw = (w + 1) / 2, hh = (h + 1) / 2;
  ImageU8 out(hw, hh);
  for (int y = 0; y < hh; ++y) {
    const std::uint8_t* a = img.row(2 * y);
    const std::uint8_t* b = img.row(std::min(2 * y + 1, h - 1));
    std::uint8_t* o = out.row(y);
    for (int x = 0; x < hw; ++x) {
      const int x1 = std::min(2 * x + 1, w - 1);
      o[x] = static_cast<std::uint8_t>((a[2 * x] + a[x1] + b[2 * x] + b[x1] + 2) >> 2);
    }
  }
  return out;
}

// `iterations` rounds of assignment and centre update on img (grid step S). The update after the
// last assignment is skipped (the labels are final) unless scale_up: then it is done and gives the
// centres in the coordinates of the image img halves (see halve): the block of half-resolution
// pixel x is full-resolution x' in {2x, 2x + 1}, centre 2x + 0.5, so the rounded mean position is
// floor((2 sum x + n) / n).
void iterate(const ImageU8& img, int S, std::int64_t m2, std::vector<Center>& centers, int iterations, ImageI32& labels,
             bool scale_up) {
  const int w = img.width, h = img.height;
  // The image, distances and labels in planes with kLanes spare columns per row (stride ws), so a
  // window rounded up to whole blocks stays inside its row (see assign_window); `labels` gets the
  // image's columns at the end.
  const std::size_t ws = std::size_t(w) + kLanes;
  std::vector<std::uint8_t> img_p(ws * std::size_t(h), 0);
  std::vector<std::int32_t> lab_p(ws * std::size_t(h), -1);
  for (int y = 0; y < h; ++y) std::copy(img.row(y), img.row(y) + w, img_p.begin() + std::ptrdiff_t(std::size_t(y) * ws));
  // Best distance so far per pixel, tagged with its iteration (see the header); all start at the
  // largest value, which every distance of the first iteration (tag 15) is below.
  constexpr int kTagShift = 28, kTagMax = 15;
  static_assert((std::uint64_t(255 * 255) * 48 * 48 + std::uint64_t(2 * 48 * 48) * 100 * 100) < (std::uint64_t(1) << kTagShift),
                "SLIC distance D' must fit below the iteration tag (region_size <= 48, compactness <= 100)");
  std::vector<std::int32_t> dist(ws * std::size_t(h), std::numeric_limits<std::int32_t>::max());  // biased
  int tag = kTagMax;
  // Row prefix sums of the grey values (int32: <= 255 * w) for the centre update, and the run
  // scratch of detail::for_each_run.
  std::vector<std::int32_t> grey_prefix(std::size_t(h) * std::size_t(w + 1));
  for (int y = 0; y < h; ++y) {
    std::int32_t* gp = grey_prefix.data() + std::size_t(y) * std::size_t(w + 1);
    const std::uint8_t* r = img.row(y);
    gp[0] = 0;
    for (int x = 0; x < w; ++x) gp[x + 1] = gp[x] + r[x];
  }
  std::vector<std::uint8_t> flags(std::size_t(w) + 8);
  // The spatial term of D' for every offset (dx, dy) in [-S, S]^2 (see assign_window), in rows of
  // side + kLanes entries: the kLanes past dx = S hold UINT32_MAX (a rounded-up block's columns past
  // the window).
  const int side = 2 * S + 1;
  const std::size_t sstride = std::size_t(side) + kLanes;
  std::vector<std::uint32_t> spatial(std::size_t(side) * sstride, std::numeric_limits<std::uint32_t>::max());
  for (int dy = -S; dy <= S; ++dy)
    for (int dx = -S; dx <= S; ++dx)
      spatial[std::size_t(dy + S) * sstride + std::size_t(dx + S)] =
          static_cast<std::uint32_t>(dx * dx + dy * dy) * static_cast<std::uint32_t>(m2);
  std::vector<std::int32_t> tagged(spatial.size());  // biased (kBias), with this iteration's tag
  // Per centre: sums of x, y and grey value and the pixel count of its pixels, together (one cache
  // line per update instead of four).
  struct Sums {
    std::int64_t x, y, i, n;
  };
  std::vector<Sums> acc(centers.size());
  for (int it = 0; it < iterations; ++it) {
    if (tag < 0) {  // tags used up (> 16 iterations): start again from the largest value
      std::fill(dist.begin(), dist.end(), std::numeric_limits<std::int32_t>::max());
      tag = kTagMax;
    }
    // The tag rides on the spatial term, so assign_window adds it without knowing.
    const std::uint32_t tag_bits = static_cast<std::uint32_t>(tag--) << kTagShift;
    for (std::size_t i = 0; i < spatial.size(); ++i)
      tagged[i] = static_cast<std::int32_t>(
          (spatial[i] == std::numeric_limits<std::uint32_t>::max() ? spatial[i] : spatial[i] + tag_bits) ^ kBias);
    for (std::size_t k = 0; k < centers.size(); ++k) {
      const Center& c = centers[k];
      const int x0 = std::max<int>(0, int(c.x) - S), x1 = std::min<int>(w - 1, int(c.x) + S);
      const int y0 = std::max<int>(0, int(c.y) - S), y1 = std::min<int>(h - 1, int(c.y) + S);
      const auto ci = static_cast<std::int32_t>(c.i), cx = static_cast<std::int32_t>(c.x), cy = static_cast<std::int32_t>(c.y);
      if (side >= 2 * kLanes)
        assign_window_wide(img_p.data(), dist.data(), lab_p.data(), ws, x0, x1, y0, y1, ci, cx, cy, tagged.data(), sstride,
                           S, static_cast<std::int32_t>(k));
      else
        assign_window(img_p.data(), dist.data(), lab_p.data(), ws, x0, (x1 - x0 + kLanes) / kLanes, y0, y1, ci, cx, cy,
                      tagged.data(), sstride, S, static_cast<std::int32_t>(k));
    }
    const bool last = it + 1 == iterations;
    if (last && !scale_up) break;  // the labels are final; the last centre update is not needed
    // Update centres (integer rounded means). Unreached pixels (-1) keep no centre. Per row, a run
    // of equal labels adds its position sums in closed form and its grey values from the row's
    // prefix sums (the same integer sums as pixel by pixel).
    std::fill(acc.begin(), acc.end(), Sums{0, 0, 0, 0});
    for (int y = 0; y < h; ++y) {
      const std::int32_t* lab = lab_p.data() + std::size_t(y) * ws;
      const std::int32_t* gp = grey_prefix.data() + std::size_t(y) * std::size_t(w + 1);
      detail::for_each_run(lab, w, flags.data(), [&](int x, int e) {
        const std::int32_t k = lab[x];
        if (k < 0) return;
        const std::int64_t len = e - x;
        Sums& a = acc[std::size_t(k)];
        a.x += (std::int64_t(x) + e - 1) * len / 2;
        a.y += std::int64_t(y) * len;
        a.i += gp[e] - gp[x];
        a.n += len;
      });
    }
    for (std::size_t k = 0; k < centers.size(); ++k) {
      const Sums& a = acc[k];
      const std::int64_t n = a.n;
      if (n == 0) {
        if (last) centers[k] = {2 * centers[k].x, 2 * centers[k].y, centers[k].i};  // scale_up: no pixels
        continue;
      }
      if (last)  // scale_up: full-resolution position of the half-resolution mean (see above)
        centers[k] = {(2 * a.x + n) / n, (2 * a.y + n) / n, (2 * a.i + n) / (2 * n)};
      else
        centers[k] = {(2 * a.x + n) / (2 * n), (2 * a.y + n) / (2 * n), (2 * a.i + n) / (2 * n)};
    }
  }
  for (int y = 0; y < h; ++y) {
    const std::int32_t* src = lab_p.data() + std::size_t(y) * ws;
    std::copy(src, src + w, labels.row(y));
  }
}

}  // namespace

Segmentation segmentation_from_labels(ImageI32 labels) {
  Segmentation seg;
  const int w = labels.width, h = labels.height;
  std::int32_t maxl = -1;
  for (auto v : labels.data) maxl = std::max(maxl, v);
  std::vector<Run> runs;
  std::vector<std::int32_t> label;
  std::vector<std::uint8_t> flags(std::size_t(w) + 8);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* l = labels.row(y);
    detail::for_each_run(l, w, flags.data(), [&](int x, int e) {
      runs.push_back(Run{y, x, e});
      label.push_back(l[x]);
    });
  }
  group_runs(seg, maxl + 1, runs, label);
  seg.labels = std::move(labels);
  return seg;
}

Segmentation slic_segment(const ImageU8& img, const SegmentationParams& p) {
  const int w = img.width, h = img.height, S = p.region_size;
  // The ranges the config enforces (common/config/schema.toml), which the integer formats rely on: the
  // 16-bit dI * S of assign_window and the iteration tag's bound (header).
  if (S < 1 || S > 48 || p.compactness < 0 || p.compactness > 100)
    throw std::invalid_argument("slic_segment: region_size must be in [1, 48] and compactness in [0, 100]");
  const std::int64_t m2 = std::int64_t(p.compactness) * p.compactness, S2 = std::int64_t(S) * S;

  // Grid centres, moved to the lowest-gradient pixel of the 3x3 neighbourhood.
  auto grad = [&](int x, int y) {
    x = std::clamp(x, 1, w - 2);
    y = std::clamp(y, 1, h - 2);
    const int gx = img.at(x + 1, y) - img.at(x - 1, y), gy = img.at(x, y + 1) - img.at(x, y - 1);
    return gx * gx + gy * gy;
  };
  std::vector<Center> centers;
  for (int cy = S / 2; cy < h; cy += S) {
    for (int cx = S / 2; cx < w; cx += S) {
      int bx = cx, by = cy, bg = std::numeric_limits<int>::max();
      if (w >= 3 && h >= 3) {
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int x = std::clamp(cx + dx, 0, w - 1), y = std::clamp(cy + dy, 0, h - 1);
            const int g = grad(x, y);
            if (g < bg) { bg = g; bx = x; by = y; }
          }
      }
      centers.push_back({bx, by, img.at(bx, by)});
    }
  }
  if (centers.empty()) centers.push_back({w / 2, h / 2, img.at(w / 2, h / 2)});

  // Coarse start (`coarse_iterations`, docs/algorithm.md 1): the first rounds on the image halved in
  // both directions (grid step S/2, the same compactness m), then the centres back at full
  // resolution for the `iterations` full-resolution rounds.
  if (p.coarse_iterations > 0 && w >= 2 && h >= 2 && S >= 2) {
    const ImageU8 half = halve(img);
    for (Center& c : centers) c = {c.x / 2, c.y / 2, c.i};
    ImageI32 coarse_labels(half.width, half.height, -1);
    iterate(half, S / 2, m2, centers, p.coarse_iterations, coarse_labels, /*scale_up=*/true);
    for (Center& c : centers) c = {std::min<std::int64_t>(c.x, w - 1), std::min<std::int64_t>(c.y, h - 1), c.i};
  }
  ImageI32 labels(w, h, -1);
  iterate(img, S, m2, centers, p.iterations, labels, /*scale_up=*/false);

  // Connectivity enforcement. The pieces are the 4-connected components of the SLIC labels, visited
  // in scan order of their first pixel; a piece smaller than the minimum joins the segment of the
  // pixel left of its first pixel (above it in column 0) — the result of a scan-order flood fill
  // (tests/cpp/core/slic_reference.hpp), computed on runs: union-find over the runs of equal label
  // that overlap between consecutive rows, the root of a piece being its first run.
  const std::int64_t min_size = std::max<std::int64_t>(1, S2 * p.min_segment_pct / 100);
  struct LRun {
    std::int32_t x0, x1, label;
  };
  std::vector<LRun> runs;
  runs.reserve(std::size_t(h) * std::size_t(2 * (w / S + 1)));  // ~2 runs per segment per row
  std::vector<std::int32_t> row_begin(std::size_t(h) + 1, 0);
  std::vector<std::uint8_t> flags(std::size_t(w) + 8);  // scratch of detail::for_each_run
  for (int y = 0; y < h; ++y) {
    const std::int32_t* lab = labels.row(y);
    detail::for_each_run(lab, w, flags.data(), [&](int x, int e) { runs.push_back({x, e, lab[x]}); });
    row_begin[std::size_t(y) + 1] = static_cast<std::int32_t>(runs.size());
  }
  detail::MinRootUnionFind uf(runs.size());
  for (int y = 1; y < h; ++y) {
    std::int32_t i = row_begin[std::size_t(y) - 1];
    const std::int32_t i_end = row_begin[std::size_t(y)];
    for (std::int32_t j = row_begin[std::size_t(y)]; j < row_begin[std::size_t(y) + 1]; ++j) {
      const LRun& b = runs[std::size_t(j)];
      while (i < i_end && runs[std::size_t(i)].x1 <= b.x0) ++i;  // runs above ending before b
      bool joined = false;  // j is still its own root until its first join
      for (std::int32_t k = i; k < i_end && runs[std::size_t(k)].x0 < b.x1; ++k) {
        if (runs[std::size_t(k)].label != b.label) continue;
        if (joined) uf.unite(k, j);  // root = first run
        else uf.attach(j, k);        // the same as unite(k, j) while j is a root: k's root < j
        joined = true;
      }
    }
  }
  std::vector<std::int32_t> parent(runs.size());  // each run's root (its piece's first run)
  std::vector<std::int64_t> size(runs.size(), 0);
  for (std::size_t j = 0; j < runs.size(); ++j) {
    parent[j] = uf.find(static_cast<std::int32_t>(j));
    size[std::size_t(parent[j])] += runs[j].x1 - runs[j].x0;
  }
  // Final labels, painted run by run, and the Segmentation's runs straight from them: a run ends
  // where the next SLIC run of the row has another final label (a piece that joined its left
  // neighbour continues that neighbour's run), so these are exactly the runs of the label image
  // (what segmentation_from_labels would find again with two more passes over it).
  Segmentation seg;
  seg.labels = ImageI32(w, h, -1);
  ImageI32& out = seg.labels;
  std::vector<std::int32_t> final_label(runs.size(), -1);  // per root run
  std::vector<Run> out_runs(runs.size());                 // row-major; the first n_out are used
  std::vector<std::int32_t> out_label(runs.size());       // final label of each
  std::size_t n_out = 0;
  std::int32_t next = 0;
  for (int y = 0; y < h; ++y) {
    std::int32_t* o = out.row(y);
    const std::size_t row_first = n_out;
    // Runs are painted left to right, so a run may be painted in whole kLanes blocks: the columns a
    // block writes past its run belong to the runs after it in the row, which overwrite them. Only
    // the last row's end, where no row follows, is painted exactly.
    const bool last_row = y + 1 == h;
    for (std::int32_t j = row_begin[std::size_t(y)]; j < row_begin[std::size_t(y) + 1]; ++j) {
      const LRun& b = runs[std::size_t(j)];
      const std::int32_t root = parent[std::size_t(j)];
      std::int32_t& fl = final_label[std::size_t(root)];
      if (root == j) {  // first pixel of the piece: (b.x0, y)
        const std::int32_t adjacent = b.x0 > 0 ? o[b.x0 - 1] : (y > 0 ? out.at(0, y - 1) : -1);
        fl = (size[std::size_t(j)] < min_size && adjacent >= 0) ? adjacent : next++;
      }
      const std::int32_t v = fl;
      if (last_row && b.x0 + kLanes * ((b.x1 - b.x0 + kLanes - 1) / kLanes) > w) {
        std::fill(o + b.x0, o + b.x1, v);
      } else {
        for (int x = b.x0; x < b.x1; x += kLanes)  // may write into the following rows' pixels (see above)
          for (int q = 0; q < kLanes; ++q) o[x + q] = v;
      }
      if (n_out > row_first && out_label[n_out - 1] == v) {
        out_runs[n_out - 1].x1 = b.x1;  // continues the previous run of this row
      } else {
        out_runs[n_out] = {y, b.x0, b.x1};
        out_label[n_out] = v;
        ++n_out;
      }
    }
  }
  out_runs.resize(n_out);
  out_label.resize(n_out);
  group_runs(seg, next, out_runs, out_label);
  return seg;
}

}  // namespace fs
