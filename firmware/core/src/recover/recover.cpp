// Not in the paper (docs/algorithm.md "5b. LR recovery"): a second choice for the segments whose
// winner the left-right check (eq. 13) rejected. Their other candidates (the K records of the cost
// stage) are tried in descending FIS score; the first whose disparity the right map confirms on
// enough of the segment's pixels is kept on exactly those pixels.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numeric>

#include "fuzzystereo/stages.hpp"

namespace fs {

int lr_recover(ImageI16& disp_lr, ImageU8* lr_mask, const ImageI16& disp_right, const Segmentation& seg,
               const SegmentCosts& costs, const SegmentDecision& dec, const FisLut& fis, const CostParams& cp,
               const LrParams& p) {
  const int K = costs.candidates_per_segment;
  const int D = costs.disparities;
  const int w = disp_lr.width;
  const int tol = p.max_diff * kDispScale;
  const auto alpha_q16 = static_cast<std::uint32_t>(std::llround(cp.alpha * kQ16One));
  auto score_of = [&](const CostCandidate& c) { return fis.lookup(c.ncc, data_cost2_q16(c.nmi, c.igsad, alpha_q16)); };
  int recovered = 0;
  // Segments are independent: each reads the right map and writes only its own pixels.
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : recovered)
#endif
  for (int s = 0; s < seg.count; ++s) {
    const std::int32_t n = seg.pixels[std::size_t(s)];
    if (n <= 0 || dec.disparity[std::size_t(s)] == kInvalidDisp) continue;
    const Run* rb = seg.runs.data() + seg.run_begin[std::size_t(s)];
    const Run* re = seg.runs.data() + seg.run_begin[std::size_t(s) + 1];
    std::int64_t valid = 0;
    for (const Run* r = rb; r != re; ++r) {
      const std::int16_t* d = disp_lr.row(r->y);
      for (int x = r->x0; x < r->x1; ++x) valid += d[x] != kInvalidDisp;
    }
    if (valid * 100 > std::int64_t(p.recover_max_valid_pct) * n) continue;
    const CostCandidate* rec = costs.candidates.data() + std::size_t(s) * std::size_t(K);
    int order[64];
    std::uint32_t score[64];
    const int kk = std::min(K, 64);
    for (int k = 0; k < kk; ++k) score[k] = score_of(rec[k]), order[k] = k;
    std::stable_sort(order, order + kk, [&](int a, int b) { return score[a] > score[b]; });
    const std::uint64_t best = dec.score[std::size_t(s)];
    for (int oi = 0; oi < kk; ++oi) {
      const int k = order[oi];
      const int d = rec[k].d;
      if (d == dec.disparity[std::size_t(s)]) continue;
      if (std::uint64_t(score[k]) * 100 < std::uint64_t(p.recover_min_score_pct) * best) break;
      // sub-pixel offset as in the WTA (parabola through the neighbouring records' scores)
      int offset = 0;
      if (cp.subpixel && d > 0 && d < D - 1 && k > 0 && k + 1 < K && rec[k - 1].d == d - 1 && rec[k + 1].d == d + 1) {
        const std::int64_t sm = score[k - 1], s0 = score[k], sp = score[k + 1];
        const std::int64_t curv = 2 * s0 - sm - sp;
        if (curv > 0) {
          const std::int64_t num = (sp - sm) * kDispScale, den = 2 * curv;
          offset = static_cast<int>((num >= 0 ? num + den / 2 : num - den / 2) / den);
          offset = std::clamp(offset, -kDispScale / 2, kDispScale / 2);
        }
      }
      const int dq = d * kDispScale + offset;
      auto consistent = [&](int x, int y) {
        const int xr = partner_x(x, static_cast<std::int16_t>(dq));
        if (xr < 0 || xr >= w) return false;
        const std::int16_t r = disp_right.row(y)[xr];
        return r != kInvalidDisp && std::abs(dq - r) <= tol;
      };
      std::int64_t c = 0;
      for (const Run* r = rb; r != re; ++r)
        for (int x = r->x0; x < r->x1; ++x) c += consistent(x, r->y);
      if (c * 100 < std::int64_t(p.recover_min_consistent_pct) * n) continue;
      for (const Run* r = rb; r != re; ++r) {
        std::int16_t* o = disp_lr.row(r->y);
        for (int x = r->x0; x < r->x1; ++x)
          if (o[x] == kInvalidDisp && consistent(x, r->y)) {
            o[x] = static_cast<std::int16_t>(dq);
            if (lr_mask) lr_mask->at(x, r->y) = 2;
          }
      }
      ++recovered;
      break;
    }
  }
  return recovered;
}

}  // namespace fs
