// Superpixel segmentation (Section III, ref. [57]): integer SLIC on grey level and position.
// Each segment is a variable-size matching window for the data costs.
//
// Distance (SLIC, Achanta et al. 2012) scaled by S^2 to stay integer:
//   D' = dI^2 * S^2 + (dx^2 + dy^2) * m^2      (uint32: dI <= 255, |dx|,|dy| <= S, S <= 48,
//                                              m <= 100 -> D' <= 1.5e8 + 4.6e7 < 2^32)
// Centres: grid of step S, then moved to the lowest-gradient pixel of their 3x3 neighbourhood.
// Centre update: integer mean (rounded) of the assigned pixels' position and grey level.
// Connectivity: pieces smaller than min_segment_pct % of S^2 join the previous neighbouring segment.
#include <algorithm>
#include <cstdlib>
#include <limits>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

namespace {

struct Center {
  std::int64_t x, y, i;
};

// One row of one centre's search window: keep the closer centre per pixel (branch-free, SIMD).
FS_TARGET_CLONES
void assign_row(const std::uint8_t* __restrict r, std::uint32_t* __restrict dr, std::int32_t* __restrict lab, int x0,
                int x1, std::int32_t ci, std::int32_t cx, std::uint32_t dy2, std::uint32_t s2, std::uint32_t mm,
                std::int32_t k) {
  for (int x = x0; x <= x1; ++x) {
    const std::int32_t di = r[x] - ci, dx = x - cx;
    const std::uint32_t d = static_cast<std::uint32_t>(di * di) * s2 + (static_cast<std::uint32_t>(dx * dx) + dy2) * mm;
    const bool closer = d < dr[x];
    dr[x] = closer ? d : dr[x];
    lab[x] = closer ? k : lab[x];
  }
}

}  // namespace

Segmentation segmentation_from_labels(ImageI32 labels) {
  Segmentation seg;
  const int w = labels.width, h = labels.height;
  std::int32_t maxl = -1;
  for (auto v : labels.data) maxl = std::max(maxl, v);
  seg.count = maxl + 1;
  seg.pixels.assign(std::size_t(seg.count), 0);
  std::vector<std::int32_t> nruns(std::size_t(seg.count), 0);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* l = labels.row(y);
    for (int x = 0; x < w; ++x) {
      ++seg.pixels[std::size_t(l[x])];
      if (x == 0 || l[x - 1] != l[x]) ++nruns[std::size_t(l[x])];
    }
  }
  seg.run_begin.assign(std::size_t(seg.count) + 1, 0);
  for (int s = 0; s < seg.count; ++s) seg.run_begin[std::size_t(s) + 1] = seg.run_begin[std::size_t(s)] + nruns[std::size_t(s)];
  seg.runs.resize(std::size_t(seg.run_begin.back()));
  std::vector<std::int32_t> fill(seg.run_begin.begin(), seg.run_begin.end() - 1);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* l = labels.row(y);
    int x = 0;
    while (x < w) {
      int e = x + 1;
      while (e < w && l[e] == l[x]) ++e;
      seg.runs[std::size_t(fill[std::size_t(l[x])]++)] = Run{y, x, e};
      x = e;
    }
  }
  seg.labels = std::move(labels);
  return seg;
}

Segmentation slic_segment(const ImageU8& img, const SegmentationParams& p) {
  const int w = img.width, h = img.height, S = p.region_size;
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
  std::vector<std::uint32_t> dist(std::size_t(w) * std::size_t(h));
  std::vector<std::int64_t> sx(centers.size()), sy(centers.size()), si(centers.size()), cnt(centers.size());
  for (int it = 0; it < p.iterations; ++it) {
    std::fill(dist.begin(), dist.end(), std::numeric_limits<std::uint32_t>::max());
    for (std::size_t k = 0; k < centers.size(); ++k) {
      const Center& c = centers[k];
      const int x0 = std::max<int>(0, int(c.x) - S), x1 = std::min<int>(w - 1, int(c.x) + S);
      const int y0 = std::max<int>(0, int(c.y) - S), y1 = std::min<int>(h - 1, int(c.y) + S);
      for (int y = y0; y <= y1; ++y) {
        const std::uint8_t* r = img.row(y);
        std::int32_t* lab = labels.row(y);
        std::uint32_t* dr = dist.data() + std::size_t(y) * std::size_t(w);
        assign_row(r, dr, lab, x0, x1, static_cast<std::int32_t>(c.i), static_cast<std::int32_t>(c.x),
                   static_cast<std::uint32_t>((y - c.y) * (y - c.y)), static_cast<std::uint32_t>(S2),
                   static_cast<std::uint32_t>(m2), static_cast<std::int32_t>(k));
      }
    }
    // Update centres (integer rounded means). Unreached pixels (-1) keep no centre.
    std::fill(sx.begin(), sx.end(), 0); std::fill(sy.begin(), sy.end(), 0);
    std::fill(si.begin(), si.end(), 0); std::fill(cnt.begin(), cnt.end(), 0);
    for (int y = 0; y < h; ++y) {
      const std::int32_t* lab = labels.row(y);
      const std::uint8_t* r = img.row(y);
      for (int x = 0; x < w; ++x) {
        const std::int32_t k = lab[x];
        if (k < 0) continue;
        sx[std::size_t(k)] += x; sy[std::size_t(k)] += y; si[std::size_t(k)] += r[x]; ++cnt[std::size_t(k)];
      }
    }
    for (std::size_t k = 0; k < centers.size(); ++k) {
      const std::int64_t n = cnt[k];
      if (n == 0) continue;
      centers[k] = {(2 * sx[k] + n) / (2 * n), (2 * sy[k] + n) / (2 * n), (2 * si[k] + n) / (2 * n)};
    }
  }

  // Connectivity enforcement (4-connected flood fill in scan order). A piece smaller than the
  // minimum joins the segment of its neighbour found first (above or left of its first pixel).
  const std::int64_t min_size = std::max<std::int64_t>(1, S2 * p.min_segment_pct / 100);
  ImageI32 out(w, h, -1);
  std::vector<std::int32_t> stack;
  std::vector<std::int32_t> piece;
  std::int32_t next = 0;
  const int dx4[4] = {-1, 0, 1, 0}, dy4[4] = {0, -1, 0, 1};
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (out.at(x, y) >= 0) continue;
      const std::int32_t src = labels.at(x, y);
      std::int32_t adjacent = -1;
      for (int k = 0; k < 4; ++k) {
        const int nx = x + dx4[k], ny = y + dy4[k];
        if (nx >= 0 && ny >= 0 && nx < w && ny < h && out.at(nx, ny) >= 0) { adjacent = out.at(nx, ny); break; }
      }
      piece.clear();
      stack.assign(1, y * w + x);
      out.at(x, y) = next;
      while (!stack.empty()) {
        const std::int32_t idx = stack.back();
        stack.pop_back();
        piece.push_back(idx);
        const int px = idx % w, py = idx / w;
        for (int k = 0; k < 4; ++k) {
          const int nx = px + dx4[k], ny = py + dy4[k];
          if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
          if (out.at(nx, ny) >= 0 || labels.at(nx, ny) != src) continue;
          out.at(nx, ny) = next;
          stack.push_back(ny * w + nx);
        }
      }
      if (static_cast<std::int64_t>(piece.size()) < min_size && adjacent >= 0) {
        for (std::int32_t idx : piece) out.data[std::size_t(idx)] = adjacent;
      } else {
        ++next;
      }
    }
  }
  return segmentation_from_labels(std::move(out));
}

}  // namespace fs
