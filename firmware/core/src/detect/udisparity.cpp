// u-disparity filtering per k-means cluster, paper eq. (24)-(25), Section III-B.
//
// For each cluster, u(x, d) = number of pixels of column x in the cluster whose rounded disparity
// is d (eq. 24-25). An obstacle is a horizontal line in this image; speckle is short or thin. A cell
// is kept when
//   (1) its support, the counts of disparities d-t .. d+t of that column (t = udisp_d_tolerance_px,
//       absorbs sub-pixel noise spreading one surface over two bins), is >= udisp_min_height_px, and
//   (2) it lies in a horizontal run of such cells (consecutive x at the same d) of length
//       >= udisp_min_run_px.
// A pixel is kept when the cell (x, round(d)) of its cluster is kept ("mapping back", Fig. 21).
// Fast version: all clusters' histograms in one pass over the image, box filter along d by a running
// sum, runs by one scan per (cluster, d) row. The reference (tests) does each cluster separately.
#include <algorithm>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

UDispResult u_disparity_filter(const ImageI16& disp, const ImageU8& labels, int clusters, int bins,
                               const DetectParams& p, UDispScratch* scratch) {
  UDispResult res;
  UDispScratch local;
  UDispScratch& sc = scratch ? *scratch : local;
  const int w = disp.width, h = disp.height;
  res.kept = ImageU8(w, h, 0);
  if (clusters <= 0) return res;
  // hist[(c * bins + d) * w + x], laid out so that a (cluster, d) row is contiguous over x.
  std::vector<std::int32_t>& hist = sc.hist;
  hist.assign(std::size_t(clusters) * std::size_t(bins) * std::size_t(w), 0);
  for (int y = 0; y < h; ++y) {
    const std::int16_t* d = disp.row(y);
    const std::uint8_t* l = labels.row(y);
    for (int x = 0; x < w; ++x)
      if (l[x] != kNoCluster) ++hist[(std::size_t(l[x]) * std::size_t(bins) + std::size_t(disp_bin(d[x]))) * std::size_t(w) + std::size_t(x)];
  }
  const int t = p.udisp_d_tolerance_px;
  std::vector<std::int32_t>& support = sc.support;
  support.resize(std::size_t(bins) * std::size_t(w));
  std::vector<std::uint8_t> ok(static_cast<std::size_t>(w));
  for (int c = 0; c < clusters; ++c) {
    const std::int32_t* hc = hist.data() + std::size_t(c) * std::size_t(bins) * std::size_t(w);
    // (1) support(d) = sum of hist(d-t .. d+t), as a running sum over d for all x at once.
    std::fill(support.begin(), support.end(), 0);
    for (int d = 0; d < bins; ++d) {
      std::int32_t* s = support.data() + std::size_t(d) * std::size_t(w);
      for (int dd = std::max(0, d - t); dd <= std::min(bins - 1, d + t); ++dd) {
        const std::int32_t* hr = hc + std::size_t(dd) * std::size_t(w);
        for (int x = 0; x < w; ++x) s[x] += hr[x];
      }
    }
    ImageU8 cells(w, bins, 0);
    for (int d = 0; d < bins; ++d) {
      const std::int32_t* s = support.data() + std::size_t(d) * std::size_t(w);
      const std::int32_t* hr = hc + std::size_t(d) * std::size_t(w);
      // A cell with no pixel of its own is never kept (nothing to map back; avoids widening runs).
      for (int x = 0; x < w; ++x) ok[std::size_t(x)] = std::uint8_t(hr[x] > 0 && s[x] >= p.udisp_min_height_px);
      // (2) horizontal runs.
      std::uint8_t* o = cells.row(d);
      for (int x = 0; x < w;) {
        if (!ok[std::size_t(x)]) {
          ++x;
          continue;
        }
        int e = x;
        while (e < w && ok[std::size_t(e)]) ++e;
        if (e - x >= p.udisp_min_run_px) std::fill(o + x, o + e, std::uint8_t(1));
        x = e;
      }
    }
    res.kept_cells.push_back(std::move(cells));
  }
  for (int y = 0; y < h; ++y) {
    const std::int16_t* d = disp.row(y);
    const std::uint8_t* l = labels.row(y);
    std::uint8_t* o = res.kept.row(y);
    for (int x = 0; x < w; ++x)
      if (l[x] != kNoCluster) o[x] = res.kept_cells[l[x]].at(x, disp_bin(d[x]));
  }
  return res;
}

}  // namespace fs::detect
