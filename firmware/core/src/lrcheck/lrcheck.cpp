// eq. (13): left-right consistency, d_l(x, y) = d_r(x - d_l(x, y), y) within max_diff.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "fuzzystereo/stages.hpp"

namespace fs {

ImageI16 left_right_check(const ImageI16& disp_left, const ImageI16& disp_right, const LrParams& p, ImageU8* mask) {
  const int w = disp_left.width, h = disp_left.height;
  ImageI16 out(w, h, kInvalidDisp);
  if (mask) *mask = ImageU8(w, h, 0);
  const int tol = p.max_diff * kDispScale;
  // Rows are independent.
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    const std::int16_t* l = disp_left.row(y);
    const std::int16_t* r = disp_right.row(y);
    std::int16_t* o = out.row(y);
    for (int x = 0; x < w; ++x) {
      const std::int16_t d = l[x];
      if (d == kInvalidDisp) continue;
      const int xr = partner_x(x, d);
      if (xr < 0 || r[xr] == kInvalidDisp) continue;
      if (std::abs(d - r[xr]) <= tol) {
        o[x] = d;
        if (mask) mask->at(x, y) = 1;
      }
    }
  }
  return out;
}

// docs/algorithm.md 5b. Segments are independent (each writes only its own pixels). Per candidate one pass over
// the segment's pixels records which are consistent (a per-thread flag buffer) and stops as soon as the rest
// can no longer reach the share; the flagged pixels are painted only when it does.
int retry_rejected_segments(ImageI16& disp_lr, ImageU8* mask, const Segmentation& seg, const SegmentCosts& costs,
                            const SegmentDecision& dec, const ImageI16& disp_right, const FisLut& fis,
                            const CostParams& cp, const LrParams& p) {
  if (p.retry_candidates <= 0) return 0;
  const int K = costs.candidates_per_segment;
  const std::size_t n = std::size_t(seg.count);
  if (costs.segments != seg.count || K <= 0 || costs.candidates.size() != n * std::size_t(K) || dec.disparity.size() != n)
    throw std::invalid_argument("retry_rejected_segments: costs, decision and segmentation disagree");
  const auto alpha_q16 = static_cast<std::uint32_t>(std::llround(cp.alpha * kQ16One));
  const int tol = p.max_diff * kDispScale;
  int recovered = 0;
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel reduction(+ : recovered)
#endif
  {
    std::vector<std::pair<std::int64_t, int>> order;  // (-score, d): best score first, ties to the smaller d
    std::vector<std::uint8_t> ok;                      // consistency of the segment's pixels, in run order
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(dynamic, 64)
#endif
    for (std::size_t s = 0; s < n; ++s) {
      const int d_win = dec.disparity[s];
      if (d_win == kInvalidDisp) continue;
      const Run* r0 = seg.runs.data() + seg.run_begin[s];
      const Run* r1 = seg.runs.data() + seg.run_begin[s + 1];
      bool kept = false;
      for (const Run* r = r0; r != r1 && !kept; ++r) {
        const std::int16_t* o = disp_lr.row(r->y);
        for (int x = r->x0; x < r->x1; ++x)
          if (o[x] != kInvalidDisp) { kept = true; break; }
      }
      if (kept) continue;
      const CostCandidate* rec = costs.candidates.data() + s * std::size_t(K);
      order.clear();
      for (int k = 0; k < K; ++k) {
        if (std::abs(rec[k].d - d_win) <= p.max_diff) continue;
        order.emplace_back(-std::int64_t(fis.lookup(rec[k].ncc, data_cost2_q16(rec[k].nmi, rec[k].igsad, alpha_q16))), rec[k].d);
      }
      std::sort(order.begin(), order.end());
      const int tries = std::min<int>(p.retry_candidates, int(order.size()));
      const std::int64_t npix = seg.pixels[s];
      const std::int64_t need = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(p.retry_min_share * double(npix))));
      ok.resize(std::size_t(npix));
      for (int t = 0; t < tries; ++t) {
        const int d = order[std::size_t(t)].second, dq = d * kDispScale;
        std::int64_t good = 0, seen = 0;
        bool hopeless = false;
        for (const Run* r = r0; r != r1 && !hopeless; ++r) {
          // Partners x - d (partner_x of an integer disparity): none left of the image (x < d), then one
          // contiguous stretch of the right row, checked branch-free (vectorised).
          const int xa = std::min(r->x1, std::max(r->x0, d));
          std::uint8_t* okr = ok.data() + seen;
          std::fill(okr, okr + (xa - r->x0), std::uint8_t(0));
          okr += xa - r->x0;
          const int m = r->x1 - xa;
          const std::int16_t* __restrict rr = disp_right.row(r->y) + (m > 0 ? xa - d : 0);  // xa >= d when m > 0
          int g = 0;
          for (int i = 0; i < m; ++i) {
            const int v = rr[i];
            const std::uint8_t c = (v != kInvalidDisp) & (dq - v <= tol) & (v - dq <= tol);
            okr[i] = c;
            g += c;
          }
          good += g;
          seen += r->x1 - r->x0;
          hopeless = good + (npix - seen) < need;
        }
        if (hopeless || good < need) continue;
        std::size_t i = 0;
        for (const Run* r = r0; r != r1; ++r) {
          std::int16_t* o = disp_lr.row(r->y);
          for (int x = r->x0; x < r->x1; ++x, ++i)
            if (ok[i]) {
              o[x] = static_cast<std::int16_t>(dq);
              if (mask) mask->at(x, r->y) = 1;
            }
        }
        ++recovered;
        break;
      }
    }
  }
  return recovered;
}

}  // namespace fs
