// Section III: disparity selection. The FIS (eq. 10-12, Table I) turns the two data costs into one
// matching quality; winner-take-all keeps the best disparity per segment.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "fuzzystereo/stages.hpp"

namespace fs {

// eq. (9): alpha*NMI + (1-alpha)*IGSAD, all Q16, rounded to nearest.
std::uint32_t data_cost2_q16(std::uint32_t nmi_q16, std::uint32_t igsad_q16, std::uint32_t alpha_q16) {
  const std::uint64_t v = std::uint64_t(alpha_q16) * nmi_q16 + std::uint64_t(kQ16One - alpha_q16) * igsad_q16;
  return static_cast<std::uint32_t>((v + (1u << 15)) >> kQ16Shift);
}

SegmentDecision fis_winner_take_all(const SegmentCosts& costs, const FisLut& fis, const CostParams& p) {
  const int D = costs.disparities;
  const auto alpha_q16 = static_cast<std::uint32_t>(std::llround(p.alpha * kQ16One));
  SegmentDecision dec;
  const std::size_t n = std::size_t(costs.segments);
  const int K = costs.candidates_per_segment;
  if (K <= 0 || costs.candidates.size() != n * std::size_t(K))
    throw std::invalid_argument("fis_winner_take_all: the costs hold no candidate records for every segment");
  if (p.subpixel && p.subpixel_every_segment && (costs.ncc.size() != n * std::size_t(D) || costs.igsad.size() != costs.ncc.size()))
    throw std::invalid_argument("fis_winner_take_all: subpixel_every_segment needs the dense NCC and IGSAD rows");
  dec.disparity.assign(n, kInvalidDisp);
  dec.disparity_q4.assign(n, kInvalidDisp);
  dec.score.assign(n, 0);
  dec.dc1.assign(n, 0);
  dec.dc2.assign(n, 0);
  auto score_of = [&](const CostCandidate& c) { return fis.lookup(c.ncc, data_cost2_q16(c.nmi, c.igsad, alpha_q16)); };
  // Segments are independent (each writes only its own entries).
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (std::size_t s = 0; s < n; ++s) {
    const CostCandidate* rec = costs.candidates.data() + s * std::size_t(K);  // ascending d
    std::int64_t best = -1;
    int kb = -1;
    for (int k = 0; k < K; ++k) {
      const std::uint32_t score = score_of(rec[k]);
      if (std::int64_t(score) > best) {  // strict, in ascending d: ties keep the smaller d
        best = score;
        kb = k;
      }
    }
    if (kb < 0) continue;
    const int d = rec[kb].d;
    dec.disparity[s] = static_cast<std::int16_t>(d);
    dec.score[s] = static_cast<std::uint32_t>(best);
    dec.dc1[s] = rec[kb].ncc;
    dec.dc2[s] = data_cost2_q16(rec[kb].nmi, rec[kb].igsad, alpha_q16);
    // Sub-pixel: parabola through the scores at d-1, d, d+1. Both neighbours are candidates
    // exactly when they are the neighbouring records (ascending d); then the scores are theirs.
    // Otherwise (subpixel_every_segment) the three are scored alike from the dense NCC / IGSAD
    // rows with the winner's NMI in eq. (9): NMI is known only for the candidates, and with
    // alpha = 0.2 it is a fifth of Data Cost 2, so NCC and IGSAD shape the parabola. Without
    // this, the ~45 % of segments whose neighbours were not candidates stayed on whole pixels.
    int offset = 0;
    if (p.subpixel && d > 0 && d < D - 1) {
      const std::int64_t s0 = best;
      std::int64_t sm = -1, sp = -1;
      if (kb > 0 && kb + 1 < K && rec[kb - 1].d == d - 1 && rec[kb + 1].d == d + 1) {
        sm = score_of(rec[kb - 1]);
        sp = score_of(rec[kb + 1]);
      } else if (p.subpixel_every_segment) {
        const std::size_t o = s * std::size_t(D) + std::size_t(d);
        const std::uint32_t nmi = rec[kb].nmi;
        auto at = [&](std::size_t i) { return fis.lookup(costs.ncc[i], data_cost2_q16(nmi, costs.igsad[i], alpha_q16)); };
        sm = at(o - 1);  // (at(o) == best: the records hold the winner's NCC and IGSAD)
        sp = at(o + 1);
      }
      const std::int64_t curv = 2 * s0 - sm - sp;  // > 0 at a strict maximum
      if (sm >= 0 && curv > 0) {
        // vertex of the parabola: (sp - sm) / (2 curv) px, in Q4 rounded to nearest, |.| <= 1/2 px
        const std::int64_t num = (sp - sm) * kDispScale, den = 2 * curv;
        offset = static_cast<int>((num >= 0 ? num + den / 2 : num - den / 2) / den);
        offset = std::clamp(offset, -kDispScale / 2, kDispScale / 2);
      }
    }
    dec.disparity_q4[s] = static_cast<std::int16_t>(d * kDispScale + offset);
  }
  return dec;
}

// Row by row through the label image (one table read per pixel, a gather the compiler vectorises)
// instead of segment by segment over the runs: each row is written once, in order. A label outside
// [0, count) (none in a valid segmentation) paints kInvalidDisp.
ImageI16 paint_segments(const Segmentation& seg, const std::vector<std::int16_t>& seg_disp_q4) {
  const int w = seg.labels.width, h = seg.labels.height;
  ImageI16 out(w, h, kInvalidDisp);
  std::vector<std::int32_t> value(std::size_t(seg.count) + 1, kInvalidDisp);  // value[count]: out of range
  for (int s = 0; s < seg.count && std::size_t(s) < seg_disp_q4.size(); ++s)
    value[std::size_t(s)] = seg_disp_q4[std::size_t(s)] < 0 ? kInvalidDisp : seg_disp_q4[std::size_t(s)];
  const auto count = static_cast<std::uint32_t>(seg.count);
  const std::int32_t* __restrict v = value.data();
  for (int y = 0; y < h; ++y) {
    const std::int32_t* __restrict lab = seg.labels.row(y);
    std::int16_t* __restrict o = out.row(y);
    for (int x = 0; x < w; ++x) {
      const std::uint32_t l = static_cast<std::uint32_t>(lab[x]);
      o[x] = static_cast<std::int16_t>(v[l < count ? l : count]);
    }
  }
  return out;
}

}  // namespace fs
