// Plain scalar reference of slic_segment (firmware/core/src/segmentation/slic.cpp): the original
// per-pixel formulation — assignment pixel by pixel, centre update by per-pixel scatter, and
// connectivity by flood fill in scan order. The fast version must produce identical labels.
#pragma once
#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "fuzzystereo/stages.hpp"

namespace fs::test {

struct RefCenter {
  std::int64_t x, y, i;
};

// `iterations` rounds of per-pixel assignment and scatter update (the update after the last round
// too; with scale_up its centres are in the coordinates of the image img halves).
inline void slic_rounds_reference(const ImageU8& img, int S, std::int64_t m2, std::vector<RefCenter>& centers,
                                  int iterations, ImageI32& labels, bool scale_up) {
  const int w = img.width, h = img.height;
  const std::int64_t S2 = std::int64_t(S) * S;
  std::vector<std::uint32_t> dist(std::size_t(w) * std::size_t(h));
  std::vector<std::int64_t> sx(centers.size()), sy(centers.size()), si(centers.size()), cnt(centers.size());
  for (int it = 0; it < iterations; ++it) {
    std::fill(dist.begin(), dist.end(), std::numeric_limits<std::uint32_t>::max());
    for (std::size_t k = 0; k < centers.size(); ++k) {
      const RefCenter& c = centers[k];
      const int x0 = std::max<int>(0, int(c.x) - S), x1 = std::min<int>(w - 1, int(c.x) + S);
      const int y0 = std::max<int>(0, int(c.y) - S), y1 = std::min<int>(h - 1, int(c.y) + S);
      for (int y = y0; y <= y1; ++y) {
        const std::uint8_t* r = img.row(y);
        std::int32_t* lab = labels.row(y);
        std::uint32_t* dr = dist.data() + std::size_t(y) * std::size_t(w);
        for (int x = x0; x <= x1; ++x) {  // D' of the header, kept when strictly closer
          const std::int64_t di = r[x] - c.i, dx = x - c.x, dy = y - c.y;
          const auto d = static_cast<std::uint32_t>(di * di * S2 + (dx * dx + dy * dy) * m2);
          if (d < dr[x]) { dr[x] = d; lab[x] = static_cast<std::int32_t>(k); }
        }
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
      const bool scale = scale_up && it + 1 == iterations;
      if (n == 0) {
        if (scale) centers[k] = {2 * centers[k].x, 2 * centers[k].y, centers[k].i};
        continue;
      }
      if (scale)  // the mean of full-resolution positions 2x + 0.5, rounded
        centers[k] = {(2 * sx[k] + n) / n, (2 * sy[k] + n) / n, (2 * si[k] + n) / (2 * n)};
      else
        centers[k] = {(2 * sx[k] + n) / (2 * n), (2 * sy[k] + n) / (2 * n), (2 * si[k] + n) / (2 * n)};
    }
  }
}

// The image halved: the rounded mean of each 2 x 2 block, the last column / row of an odd size repeated.
inline ImageU8 halve_reference(const ImageU8& img) {
  const int w = img.width, h = img.height;
  ImageU8 out((w + 1) / 2, (h + 1) / 2);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      const int xa = 2 * x, xb = std::min(2 * x + 1, w - 1), ya = 2 * y, yb = std::min(2 * y + 1, h - 1);
      out.at(x, y) = static_cast<std::uint8_t>((img.at(xa, ya) + img.at(xb, ya) + img.at(xa, yb) + img.at(xb, yb) + 2) / 4);
    }
  return out;
}

inline Segmentation slic_segment_reference(const ImageU8& img, const SegmentationParams& p) {
  const int w = img.width, h = img.height, S = p.region_size;
  const std::int64_t m2 = std::int64_t(p.compactness) * p.compactness, S2 = std::int64_t(S) * S;

  // Grid centres, moved to the lowest-gradient pixel of the 3x3 neighbourhood.
  auto grad = [&](int x, int y) {
    x = std::clamp(x, 1, w - 2);
    y = std::clamp(y, 1, h - 2);
    const int gx = img.at(x + 1, y) - img.at(x - 1, y), gy = img.at(x, y + 1) - img.at(x, y - 1);
    return gx * gx + gy * gy;
  };
  std::vector<RefCenter> centers;
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

  if (p.coarse_iterations > 0 && w >= 2 && h >= 2 && S >= 2) {  // coarse start on the halved image
    const ImageU8 half = halve_reference(img);
    for (RefCenter& c : centers) c = {c.x / 2, c.y / 2, c.i};
    ImageI32 coarse(half.width, half.height, -1);
    slic_rounds_reference(half, S / 2, m2, centers, p.coarse_iterations, coarse, true);
    for (RefCenter& c : centers) c = {std::min<std::int64_t>(c.x, w - 1), std::min<std::int64_t>(c.y, h - 1), c.i};
  }
  ImageI32 labels(w, h, -1);
  slic_rounds_reference(img, S, m2, centers, p.iterations, labels, false);

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

}  // namespace fs::test
