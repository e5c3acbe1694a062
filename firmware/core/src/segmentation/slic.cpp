// Superpixel segmentation (Section III, ref. [57]): integer SLIC on grey level and position.
// Each segment is a variable-size matching window for the data costs.
//
// Distance (SLIC, Achanta et al. 2012) scaled by S^2 to stay integer:
//   D' = dI^2 * S^2 + (dx^2 + dy^2) * m^2      (uint32: dI <= 255, |dx|,|dy| <= S, S <= 48,
//                                              m <= 100 -> D' <= 1.5e8 + 4.6e7 < 2^28)
// Iteration tag: the best distance per pixel is kept as tag << 28 | D' (D' < 2^28 by the bound above),
// the tag one lower each iteration, so every distance of an earlier iteration compares larger than any
// of this one — what refilling the distances with UINT32_MAX before each iteration did, without the
// pass over the image (16 iterations per fill).
// Centres: grid of step S, then moved to the lowest-gradient pixel of their 3x3 neighbourhood.
// Centre update: integer mean (rounded) of the assigned pixels' position and grey level.
// Connectivity: pieces smaller than min_segment_pct % of S^2 join the previous neighbouring segment.
#include <algorithm>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {

struct Center {
  std::int64_t x, y, i;
};

// One centre's search window [x0, x1] x [y0, y1]: keep the closer centre per pixel (branch-free,
// SIMD; one call per window so the clone dispatch and loop set-up are paid once per centre). The
// spatial term (dx^2 + dy^2) * m^2 is read from `spatial`, the (2S+1) x (2S+1) table of every
// offset from a centre (the same for all centres: their positions are integers), so a pixel costs
// one 16-bit multiplication ((dI * S)^2, below) instead of three.
FS_TARGET_CLONES
void assign_window(const ImageU8& img, std::uint32_t* __restrict dist, ImageI32& labels, int x0, int x1, int y0, int y1,
                   std::int32_t ci, std::int32_t cx, std::int32_t cy, const std::uint32_t* spatial,
                   int S, std::int32_t k) {
  const int w = img.width, side = 2 * S + 1;
  const auto ci16 = static_cast<std::int16_t>(ci), s16 = static_cast<std::int16_t>(S);
  for (int y = y0; y <= y1; ++y) {
    const std::uint8_t* __restrict r = img.row(y);
    std::uint32_t* __restrict dr = dist + std::size_t(y) * std::size_t(w);
    std::int32_t* __restrict lab = labels.row(y);
    // sp[x - x0] = (dx^2 + dy^2) * m^2 for dx = x - cx (x0 >= cx - S)
    const std::uint32_t* __restrict sp = spatial + std::size_t(y - cy + S) * std::size_t(side) + std::size_t(x0 - cx + S);
    for (int x = x0; x <= x1; ++x) {
      // (dI * S)^2 = dI^2 * S^2 with dI * S in int16 (|dI| <= 255, S <= 48: <= 12240), so the square is a
      // 16 x 16 -> 32-bit multiply (one vpmaddwd-class instruction) instead of a 32-bit one.
      const auto t = static_cast<std::int16_t>(static_cast<std::int16_t>(r[x] - ci16) * s16);
      const std::uint32_t d = static_cast<std::uint32_t>(std::int32_t(t) * std::int32_t(t)) + sp[x - x0];
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

  ImageI32 labels(w, h, -1);
  // Best distance so far per pixel, tagged with its iteration (see the header); all start at the
  // largest value, which every distance of the first iteration (tag 15) is below.
  constexpr int kTagShift = 28, kTagMax = 15;
  static_assert((std::uint64_t(255 * 255) * 48 * 48 + std::uint64_t(2 * 48 * 48) * 100 * 100) < (std::uint64_t(1) << kTagShift),
                "SLIC distance D' must fit below the iteration tag (region_size <= 48, compactness <= 100)");
  std::vector<std::uint32_t> dist(std::size_t(w) * std::size_t(h), std::numeric_limits<std::uint32_t>::max());
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
  // The spatial term of D' for every offset (dx, dy) in [-S, S]^2 (see assign_window).
  const int side = 2 * S + 1;
  std::vector<std::uint32_t> spatial(std::size_t(side) * std::size_t(side)), tagged(spatial.size());
  for (int dy = -S; dy <= S; ++dy)
    for (int dx = -S; dx <= S; ++dx)
      spatial[std::size_t(dy + S) * std::size_t(side) + std::size_t(dx + S)] =
          static_cast<std::uint32_t>(dx * dx + dy * dy) * static_cast<std::uint32_t>(m2);
  std::vector<std::int64_t> sx(centers.size()), sy(centers.size()), si(centers.size()), cnt(centers.size());
  for (int it = 0; it < p.iterations; ++it) {
    if (tag < 0) {  // tags used up (> 16 iterations): start again from the largest value
      std::fill(dist.begin(), dist.end(), std::numeric_limits<std::uint32_t>::max());
      tag = kTagMax;
    }
    // The tag rides on the spatial term, so assign_window adds it without knowing.
    const std::uint32_t tag_bits = static_cast<std::uint32_t>(tag--) << kTagShift;
    for (std::size_t i = 0; i < spatial.size(); ++i) tagged[i] = spatial[i] + tag_bits;
    for (std::size_t k = 0; k < centers.size(); ++k) {
      const Center& c = centers[k];
      const int x0 = std::max<int>(0, int(c.x) - S), x1 = std::min<int>(w - 1, int(c.x) + S);
      const int y0 = std::max<int>(0, int(c.y) - S), y1 = std::min<int>(h - 1, int(c.y) + S);
      assign_window(img, dist.data(), labels, x0, x1, y0, y1, static_cast<std::int32_t>(c.i),
                    static_cast<std::int32_t>(c.x), static_cast<std::int32_t>(c.y), tagged.data(), S, static_cast<std::int32_t>(k));
    }
    if (it + 1 == p.iterations) break;  // the labels are final; the last centre update is not needed
    // Update centres (integer rounded means). Unreached pixels (-1) keep no centre. Per row, a run
    // of equal labels adds its position sums in closed form and its grey values from the row's
    // prefix sums (the same integer sums as pixel by pixel).
    std::fill(sx.begin(), sx.end(), 0); std::fill(sy.begin(), sy.end(), 0);
    std::fill(si.begin(), si.end(), 0); std::fill(cnt.begin(), cnt.end(), 0);
    for (int y = 0; y < h; ++y) {
      const std::int32_t* lab = labels.row(y);
      const std::int32_t* gp = grey_prefix.data() + std::size_t(y) * std::size_t(w + 1);
      detail::for_each_run(lab, w, flags.data(), [&](int x, int e) {
        const std::int32_t k = lab[x];
        if (k < 0) return;
        const std::int64_t len = e - x;
        sx[std::size_t(k)] += (std::int64_t(x) + e - 1) * len / 2;
        sy[std::size_t(k)] += std::int64_t(y) * len;
        si[std::size_t(k)] += gp[e] - gp[x];
        cnt[std::size_t(k)] += len;
      });
    }
    for (std::size_t k = 0; k < centers.size(); ++k) {
      const std::int64_t n = cnt[k];
      if (n == 0) continue;
      centers[k] = {(2 * sx[k] + n) / (2 * n), (2 * sy[k] + n) / (2 * n), (2 * si[k] + n) / (2 * n)};
    }
  }

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
  std::vector<std::int32_t> row_begin(std::size_t(h) + 1, 0);
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
      for (std::int32_t k = i; k < i_end && runs[std::size_t(k)].x0 < b.x1; ++k) {
        if (runs[std::size_t(k)].label != b.label) continue;
        uf.unite(k, j);  // root = first run
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
  std::vector<Run> out_runs;                              // row-major
  std::vector<std::int32_t> out_label;                    // final label of each
  out_runs.reserve(runs.size());
  out_label.reserve(runs.size());
  std::int32_t next = 0;
  for (int y = 0; y < h; ++y) {
    std::int32_t* o = out.row(y);
    const std::size_t row_first = out_runs.size();
    for (std::int32_t j = row_begin[std::size_t(y)]; j < row_begin[std::size_t(y) + 1]; ++j) {
      const LRun& b = runs[std::size_t(j)];
      const std::int32_t root = parent[std::size_t(j)];
      std::int32_t& fl = final_label[std::size_t(root)];
      if (root == j) {  // first pixel of the piece: (b.x0, y)
        const std::int32_t adjacent = b.x0 > 0 ? o[b.x0 - 1] : (y > 0 ? out.at(0, y - 1) : -1);
        fl = (size[std::size_t(j)] < min_size && adjacent >= 0) ? adjacent : next++;
      }
      std::fill(o + b.x0, o + b.x1, fl);
      if (out_runs.size() > row_first && out_label.back() == fl) {
        out_runs.back().x1 = b.x1;  // continues the previous run of this row
      } else {
        out_runs.push_back({y, b.x0, b.x1});
        out_label.push_back(fl);
      }
    }
  }
  group_runs(seg, next, out_runs, out_label);
  return seg;
}

}  // namespace fs
