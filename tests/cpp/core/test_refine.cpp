// WTA, left-right check (eq. 13) and ESR (eq. 14-15) against plain scalar references.
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <algorithm>
#include <tuple>
#include <random>

#include <gtest/gtest.h>

#include "config.hpp"
#include "fuzzystereo/stages.hpp"
#include "test_util.hpp"

namespace fs {
namespace {

ImageI16 random_disp(int w, int h, int D, unsigned seed, int invalid_pct, int block) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> ud(0, D - 1), up(0, 99);
  ImageI16 img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if ((x % block) == 0 || (y % block) == 0 || (x + y) % 7 == 0) img.at(x, y) = static_cast<std::int16_t>(ud(rng) * kDispScale + (x * 5 + y) % 16);
      else img.at(x, y) = img.at(x - 1, y);
      if (up(rng) < invalid_pct) img.at(x, y) = kInvalidDisp;
    }
  return img;
}

// Scalar reference of the WTA on dense per-(segment, d) costs with an evaluated flag: scan every d
// in ascending order, keep the first best FIS score, then the sub-pixel parabola when both
// neighbours were evaluated.
struct DenseCosts {
  int segments = 0, D = 0;
  std::vector<std::uint32_t> ncc, igsad, nmi;
  std::vector<std::uint8_t> valid;
};

SegmentDecision reference_wta(const DenseCosts& c, const FisLut& lut, const CostParams& p) {
  const auto a16 = std::uint32_t(std::llround(p.alpha * 65536));
  SegmentDecision dec;
  dec.disparity.assign(std::size_t(c.segments), kInvalidDisp);
  dec.disparity_q4.assign(std::size_t(c.segments), kInvalidDisp);
  dec.score.assign(std::size_t(c.segments), 0);
  auto score = [&](std::size_t i) { return lut.lookup(c.ncc[i], data_cost2_q16(c.nmi[i], c.igsad[i], a16)); };
  for (int s = 0; s < c.segments; ++s) {
    const std::size_t off = std::size_t(s) * std::size_t(c.D);
    int best = -1;
    std::uint32_t bs = 0;
    for (int d = 0; d < c.D; ++d)
      if (c.valid[off + std::size_t(d)] && (best < 0 || score(off + std::size_t(d)) > bs)) {
        best = d;
        bs = score(off + std::size_t(d));
      }
    if (best < 0) continue;
    int offset = 0;
    const std::size_t ib = off + std::size_t(best);
    if (p.subpixel && best > 0 && best < c.D - 1) {
      double sm = -1, sp = -1;
      if (c.valid[ib - 1] && c.valid[ib + 1]) {  // both neighbours evaluated: their own scores
        sm = score(ib - 1);
        sp = score(ib + 1);
      } else if (p.subpixel_every_segment) {  // otherwise with the winner's NMI
        auto with_winner_nmi = [&](std::size_t i) { return lut.lookup(c.ncc[i], data_cost2_q16(c.nmi[ib], c.igsad[i], a16)); };
        sm = with_winner_nmi(ib - 1);
        sp = with_winner_nmi(ib + 1);
      }
      const double curv = 2.0 * bs - sm - sp;
      if (sm >= 0 && curv > 0) offset = static_cast<int>(std::clamp(std::lround((sp - sm) * 16.0 / (2.0 * curv)), -8L, 8L));
    }
    dec.disparity[std::size_t(s)] = static_cast<std::int16_t>(best);
    dec.disparity_q4[std::size_t(s)] = static_cast<std::int16_t>(best * 16 + offset);
    dec.score[std::size_t(s)] = bs;
  }
  return dec;
}

// The WTA on the candidate records against the dense scan, with K of D disparities per segment
// (random subsets: many adjacent pairs, so the sub-pixel step runs) and with every disparity.
TEST(Wta, CandidateRecordsDecideAsTheDenseScan) {
  const FisLut& lut = *FisLut::cached(load_fis_definition(""), 257);
  for (auto [K, D, subpixel, every] : {std::tuple{11, 17, true, true}, {11, 17, true, false}, {11, 17, false, true},
                                       {17, 17, true, true}, {3, 40, true, true}, {3, 40, true, false}}) {
    std::mt19937 rng(static_cast<unsigned>(3 + K + D));
    std::uniform_int_distribution<std::uint32_t> u(0, 65536);
    const int S = 60;
    DenseCosts dense;
    dense.segments = S;
    dense.D = D;
    SegmentCosts c;
    c.segments = S;
    c.disparities = D;
    c.candidates_per_segment = K;
    for (int i = 0; i < S * D; ++i) {
      dense.ncc.push_back(u(rng));
      dense.igsad.push_back(u(rng));
      dense.nmi.push_back(u(rng));
    }
    c.ncc = dense.ncc;
    c.igsad = dense.igsad;
    dense.valid.assign(std::size_t(S * D), 0);
    for (int s = 0; s < S; ++s) {
      std::vector<int> ds(static_cast<std::size_t>(D));
      std::iota(ds.begin(), ds.end(), 0);
      std::shuffle(ds.begin(), ds.end(), rng);
      ds.resize(std::size_t(K));
      std::sort(ds.begin(), ds.end());
      for (int d : ds) {
        const std::size_t i = std::size_t(s * D + d);
        dense.valid[i] = 1;
        c.candidates.push_back({dense.ncc[i], dense.igsad[i], dense.nmi[i], d});
      }
    }
    CostParams p;
    p.alpha = 0.3;
    p.subpixel = subpixel;
    p.subpixel_every_segment = every;
    const SegmentDecision a = fis_winner_take_all(c, lut, p), b = reference_wta(dense, lut, p);
    SCOPED_TRACE(::testing::Message() << "K=" << K << " D=" << D << " subpixel=" << subpixel << " every=" << every);
    EXPECT_EQ(a.disparity, b.disparity);
    EXPECT_EQ(a.disparity_q4, b.disparity_q4);
    EXPECT_EQ(a.score, b.score);
    // Segments moved off the whole pixel, those whose winner has both neighbours among the
    // candidates and the others.
    int moved_pair = 0, moved_other = 0, other = 0;
    for (int s = 0; s < S; ++s) {
      const int d = a.disparity[std::size_t(s)];
      const std::size_t i = std::size_t(s * D + d);
      const bool interior = d > 0 && d < D - 1, pair = interior && dense.valid[i - 1] && dense.valid[i + 1];
      const bool moved = a.disparity_q4[std::size_t(s)] % 16 != 0;
      (pair ? moved_pair : moved_other) += moved;
      other += interior && !pair;
    }
    if (subpixel && 2 * K > D) {  // dense enough for adjacent triples
      EXPECT_GT(moved_pair, 0);
    }
    if (subpixel && every && other > 5) {  // the winner's-NMI fallback ran
      EXPECT_GT(moved_other, 0);
    }
    if (!subpixel || !every) {
      EXPECT_EQ(moved_other, 0);
    }
    if (!subpixel) {
      EXPECT_EQ(moved_pair, 0);
    }
  }
}

TEST(Wta, RejectsCostsWithoutCandidateRecords) {
  const FisLut& lut = *FisLut::cached(load_fis_definition(""), 257);
  SegmentCosts c;
  c.segments = 2;
  c.disparities = 4;
  c.ncc.assign(8, 0);
  c.igsad.assign(8, 0);
  EXPECT_THROW(fis_winner_take_all(c, lut, CostParams{}), std::invalid_argument);
  // Records present but no dense rows: the every-segment sub-pixel step cannot run.
  c.candidates_per_segment = 1;
  c.candidates = {{0, 0, 0, 1}, {0, 0, 0, 2}};
  c.ncc.clear();
  CostParams every;
  every.subpixel_every_segment = true;
  EXPECT_THROW(fis_winner_take_all(c, lut, every), std::invalid_argument);
  EXPECT_NO_THROW(fis_winner_take_all(c, lut, CostParams{}));  // default: off
}

// paint_segments (row-wise table read through the labels) against painting the runs segment by
// segment, on SLIC segmentations of odd-sized textured images with some segments left unassigned.
TEST(Wta, PaintMatchesRunWiseReference) {
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const int w = 53 + 4 * static_cast<int>(seed), h = 31 + 2 * static_cast<int>(seed);
    SegmentationParams sp;
    sp.region_size = 6;
    const Segmentation seg = slic_segment(test::texture_image(w, h, seed), sp);
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> ud(-1, 40 * kDispScale);
    std::vector<std::int16_t> disp(std::size_t(seg.count));
    for (auto& d : disp) d = static_cast<std::int16_t>(ud(rng));  // -1 (and other < 0) = no disparity
    ImageI16 ref(w, h, kInvalidDisp);
    for (int sgm = 0; sgm < seg.count; ++sgm)
      for (std::int32_t r = seg.run_begin[std::size_t(sgm)]; r < seg.run_begin[std::size_t(sgm) + 1]; ++r) {
        const fs::Run& run = seg.runs[std::size_t(r)];
        for (int x = run.x0; x < run.x1; ++x) ref.at(x, run.y) = disp[std::size_t(sgm)] < 0 ? kInvalidDisp : disp[std::size_t(sgm)];
      }
    ASSERT_EQ(paint_segments(seg, disp).data, ref.data) << "seed " << seed;
  }
}

TEST(LrCheck, MatchesScalarReference) {
  const ImageI16 l = random_disp(53, 19, 12, 1u, 5, 4), r = random_disp(53, 19, 12, 2u, 5, 4);
  for (int tol : {0, 1, 3}) {
    LrParams p;
    p.max_diff = tol;
    ImageU8 mask;
    const ImageI16 out = left_right_check(l, r, p, &mask);
    for (int y = 0; y < 19; ++y)
      for (int x = 0; x < 53; ++x) {
        const int d = l.at(x, y);
        bool ok = false;
        if (d >= 0) {
          const int xr = x - int(std::floor(d / 16.0 + 0.5));  // eq. (13), nearest pixel
          ok = xr >= 0 && r.at(xr, y) >= 0 && std::abs(d - r.at(xr, y)) <= tol * kDispScale;
        }
        EXPECT_EQ(out.at(x, y), ok ? d : kInvalidDisp);
        EXPECT_EQ(mask.at(x, y), ok ? 1 : 0);
      }
  }
}

// docs/algorithm.md 5b: the candidate retry, written pixel by pixel from the rule (labels scanned per
// segment, candidates ranked by a full sort of (score desc, d asc), consistency counted per pixel).
ImageI16 retry_reference(const ImageI16& lr, const ImageI32& labels, int nseg, const SegmentCosts& c,
                         const SegmentDecision& dec, const ImageI16& right, const FisLut& lut, const CostParams& cp,
                         const LrParams& p, ImageU8& mask) {
  ImageI16 out = lr;
  const auto alpha = static_cast<std::uint32_t>(std::llround(cp.alpha * kQ16One));
  for (int s = 0; s < nseg; ++s) {
    if (dec.disparity[std::size_t(s)] == kInvalidDisp) continue;
    int npix = 0, kept = 0;
    for (int y = 0; y < labels.height; ++y)
      for (int x = 0; x < labels.width; ++x)
        if (labels.at(x, y) == s) { ++npix; kept += lr.at(x, y) != kInvalidDisp; }
    if (kept > 0 || npix == 0) continue;
    std::vector<std::tuple<std::int64_t, int>> order;
    for (int k = 0; k < c.candidates_per_segment; ++k) {
      const CostCandidate& cc = c.candidates[std::size_t(s * c.candidates_per_segment + k)];
      if (std::abs(cc.d - dec.disparity[std::size_t(s)]) <= p.max_diff) continue;
      order.emplace_back(-std::int64_t(lut.lookup(cc.ncc, data_cost2_q16(cc.nmi, cc.igsad, alpha))), cc.d);
    }
    std::sort(order.begin(), order.end());
    for (int t = 0; t < std::min<int>(p.retry_candidates, int(order.size())); ++t) {
      const int d = std::get<1>(order[std::size_t(t)]);
      auto ok = [&](int x, int y) {
        const int xr = x - d;
        return xr >= 0 && right.at(xr, y) != kInvalidDisp && std::abs(d * kDispScale - right.at(xr, y)) <= p.max_diff * kDispScale;
      };
      int n = 0;
      for (int y = 0; y < labels.height; ++y)
        for (int x = 0; x < labels.width; ++x) n += labels.at(x, y) == s && ok(x, y);
      if (n == 0 || double(n) < p.retry_min_share * npix - 1e-9) continue;
      for (int y = 0; y < labels.height; ++y)
        for (int x = 0; x < labels.width; ++x)
          if (labels.at(x, y) == s && ok(x, y)) { out.at(x, y) = static_cast<std::int16_t>(d * kDispScale); mask.at(x, y) = 1; }
      break;
    }
  }
  return out;
}

// A label image of vertical stripes (width 5) cut every 4 rows: runs of several rows per segment.
ImageI32 stripe_labels(int w, int h, int& nseg) {
  ImageI32 lab(w, h);
  const int cols = (w + 4) / 5;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) lab.at(x, y) = (y / 4) * cols + x / 5;
  nseg = ((h + 3) / 4) * cols;
  return lab;
}

TEST(LrRetry, TriesTheOtherCandidatesBestFirstAndKeepsTheFirstConsistentOne) {
  // One segment (10 x 4 px at x >= 20), winner d = 5 rejected on every pixel. Candidates d = 2 (second
  // best score), d = 9 (third). The right map agrees with d = 9 everywhere and with d = 2 on 3 of 10
  // columns: with a 0.7 share d = 2 fails and d = 9 is kept; with 0.2 d = 2 is kept on its 30 %.
  const int w = 40, h = 4;
  ImageI32 lab(w, h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 20; x < 30; ++x) lab.at(x, y) = 1;
  const Segmentation seg = segmentation_from_labels(lab);
  const FisLut& lut = *FisLut::cached(load_fis_definition(""), 257);
  SegmentCosts c;
  c.segments = 2;
  c.disparities = 12;
  c.candidates_per_segment = 3;
  const std::uint32_t hi = 60000, mid = 40000, lo = 20000;
  c.candidates = {{hi, hi, hi, 1}, {mid, mid, mid, 2}, {lo, lo, lo, 3},   // segment 0: not rejected (lr valid)
                  {mid, mid, mid, 2}, {hi, hi, hi, 5}, {lo, lo, lo, 9}};  // segment 1
  ASSERT_GT(lut.lookup(hi, hi), lut.lookup(mid, mid));
  ASSERT_GT(lut.lookup(mid, mid), lut.lookup(lo, lo));
  SegmentDecision dec;
  dec.disparity = {1, 5};
  ImageI16 right(w, h, kInvalidDisp);
  for (int y = 0; y < h; ++y)
    for (int x = 20; x < 30; ++x) {
      right.at(x - 9, y) = 9 * kDispScale;
      if (x >= 27) right.at(x - 2, y) = 2 * kDispScale;
    }
  ImageI16 lr(w, h, kInvalidDisp);
  lr.at(3, 0) = 1 * kDispScale;  // segment 0 keeps a pixel: untouched
  CostParams cp;
  for (auto [share, d_kept, n_kept] : {std::tuple{0.7, 9, 40}, {0.2, 2, 12}}) {
    LrParams p;
    p.retry_candidates = 3;
    p.retry_min_share = share;
    ImageI16 out = lr;
    ImageU8 mask(w, h, 0);
    EXPECT_EQ(retry_rejected_segments(out, &mask, seg, c, dec, right, lut, cp, p), 1);
    int n = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        if (lab.at(x, y) == 0) { EXPECT_EQ(out.at(x, y), lr.at(x, y)); continue; }
        if (out.at(x, y) == kInvalidDisp) continue;
        EXPECT_EQ(out.at(x, y), d_kept * kDispScale);
        EXPECT_EQ(mask.at(x, y), 1);
        ++n;
      }
    EXPECT_EQ(n, n_kept) << "share " << share;
    p.retry_candidates = 1;  // only d = 2 is tried
    ImageI16 one = lr;
    EXPECT_EQ(retry_rejected_segments(one, nullptr, seg, c, dec, right, lut, cp, p), share < 0.3 ? 1 : 0);
  }
  LrParams off;
  off.retry_candidates = 0;
  ImageI16 same = lr;
  EXPECT_EQ(retry_rejected_segments(same, nullptr, seg, c, dec, right, lut, cp, off), 0);
  EXPECT_EQ(same.data, lr.data);
}

TEST(LrRetry, MatchesPixelByPixelReference) {
  const FisLut& lut = *FisLut::cached(load_fis_definition(""), 257);
  int recovered = 0, changed = 0;
  for (unsigned seed : {1u, 2u, 3u}) {
    for (auto [w, h] : {std::pair{37, 13}, {61, 22}}) {
      int nseg = 0;
      const Segmentation seg = segmentation_from_labels(stripe_labels(w, h, nseg));
      ASSERT_EQ(seg.count, nseg);
      std::mt19937 rng(seed * 97 + unsigned(w));
      std::uniform_int_distribution<int> ud(0, 11), uq(0, 65536), up(0, 99);
      SegmentCosts c;
      c.segments = nseg;
      c.disparities = 12;
      c.candidates_per_segment = 5;
      SegmentDecision dec;
      for (int s = 0; s < nseg; ++s) {
        for (int k = 0; k < 5; ++k)
          c.candidates.push_back({std::uint32_t(uq(rng)), std::uint32_t(uq(rng)), std::uint32_t(uq(rng)), (k * 3 + ud(rng) % 3) % 12});
        dec.disparity.push_back(up(rng) < 5 ? kInvalidDisp : static_cast<std::int16_t>(ud(rng)));
      }
      // Left map: most segments rejected whole (invalid), some keep a pixel; right map: stripes of
      // integer disparities, some invalid.
      ImageI16 lr(w, h, kInvalidDisp), right(w, h);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          if (up(rng) < 3) lr.at(x, y) = static_cast<std::int16_t>(ud(rng) * kDispScale);
          right.at(x, y) = up(rng) < 10 ? kInvalidDisp : static_cast<std::int16_t>(((x / 3 + y) % 12) * kDispScale + (up(rng) % 3) * 8 - 8);
        }
      for (int tries : {1, 2, 5}) {
        for (double share : {0.1, 0.5, 0.9}) {
          LrParams p;
          p.max_diff = 1;
          p.retry_candidates = tries;
          p.retry_min_share = share;
          CostParams cp;
          ImageU8 m_ref(w, h, 0), m_out(w, h, 0);
          const ImageI16 ref = retry_reference(lr, seg.labels, nseg, c, dec, right, lut, cp, p, m_ref);
          ImageI16 out = lr;
          recovered += retry_rejected_segments(out, &m_out, seg, c, dec, right, lut, cp, p);
          changed += out.data != lr.data;
          ASSERT_EQ(out.data, ref.data) << "seed " << seed << " " << w << "x" << h << " tries " << tries << " share " << share;
          ASSERT_EQ(m_out.data, m_ref.data);
        }
      }
    }
  }
  EXPECT_GT(recovered, 50);  // the cases do exercise the retry (and not every one: see the shares)
  EXPECT_LT(changed, 54);
  std::printf("retry: %d segments recovered, %d of 54 cases changed the map\n", recovered, changed);
}

std::int32_t entropy_reference(const ImageI16& d, int cx, int cy, int win) {
  std::map<int, int> hist;
  int n = 0;
  for (int y = cy - win / 2; y <= cy + win / 2; ++y)
    for (int x = cx - win / 2; x <= cx + win / 2; ++x) {
      if (x < 0 || y < 0 || x >= d.width || y >= d.height || d.at(x, y) < 0) continue;
      ++hist[int(std::floor(d.at(x, y) / 16.0 + 0.5))];
      ++n;
    }
  if (n == 0) return 0;
  auto T = [](int c) { return c < 2 ? 0ull : std::uint64_t(std::llround(c * std::log2(double(c)) * 65536.0)); };
  std::uint64_t s = 0;
  for (auto [k, c] : hist) s += T(c);
  return std::int32_t((T(n) - s + std::uint64_t(n) / 2) / std::uint64_t(n));
}

TEST(Esr, BlockEntropyIncrementalEqualsRecomputation) {
  for (auto [w, h, win] : {std::tuple{41, 17, 5}, {23, 31, 9}, {7, 5, 11}, {64, 3, 3}}) {
    const ImageI16 d = random_disp(w, h, 20, 7u, 10, 3);
    const ImageI32 e = block_entropy(d, win, 20);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) ASSERT_EQ(e.at(x, y), entropy_reference(d, x, y, win)) << x << "," << y << " w" << win;
  }
}

TEST(Esr, BlockEntropyOnPiecewiseConstantMaps) {
  // Segment-like patches (vertical runs longer than the window, runs of equal integer bins with
  // different Q4 values, invalid patches): the run-wise column updates against recomputation.
  // Patches wider than the window (pw = 13, 29) make the column entering a block equal to the one
  // leaving it, the case the entropy is carried over unchanged.
  for (auto [w, h, win, pw] : {std::tuple{43, 37, 5, 5}, {29, 23, 3, 5}, {31, 41, 9, 5}, {61, 37, 5, 13},
                               {57, 29, 3, 13}, {75, 41, 9, 29}}) {
    std::mt19937 rng(11u);
    std::uniform_int_distribution<int> ud(0, 11), up(0, 99);
    std::vector<std::int16_t> patch(std::size_t((w / pw + 1) * (h / 7 + 1)));
    for (auto& v : patch) v = up(rng) < 10 ? kInvalidDisp : static_cast<std::int16_t>(ud(rng) * kDispScale);
    ImageI16 d(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const std::int16_t v = patch[std::size_t((y / 7) * (w / pw + 1) + x / pw)];
        d.at(x, y) = v == kInvalidDisp ? v : static_cast<std::int16_t>(v + (y % 3 == 0 ? 3 : 5));  // same bin
      }
    const ImageI32 e = block_entropy(d, win, 12);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) ASSERT_EQ(e.at(x, y), entropy_reference(d, x, y, win)) << x << "," << y << " w" << win;
  }
}

TEST(Esr, BlockEntropyWithANeedMaskEqualsTheFullImageWhereNeeded) {
  // Needed pixels alone (ESR's masks): random masks from sparse (long gaps, the rebuild path) to
  // dense (slides), on random and piecewise-constant maps of odd sizes; every window path (the
  // reciprocal up to 9, the 32-bit division above). Unneeded pixels are 0.
  for (auto [w, h, win, pct] : {std::tuple{41, 17, 5, 50}, {23, 31, 9, 10}, {7, 5, 11, 60}, {64, 3, 3, 90},
                                {77, 29, 5, 3}, {53, 21, 13, 30}, {39, 19, 7, 100}}) {
    for (const bool patches : {false, true}) {
      ImageI16 d = random_disp(w, h, 20, 17u + unsigned(win), 10, 3);
      if (patches)
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) d.at(x, y) = d.at(x - x % 6, y - y % 5);
      std::mt19937 rng(unsigned(w * 7 + pct));
      std::uniform_int_distribution<int> u(0, 99);
      ImageU8 need(w, h, 0);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) need.at(x, y) = u(rng) < pct ? 1 : 0;
      const ImageI32 full = block_entropy(d, win, 20), part = block_entropy(d, win, 20, &need);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          ASSERT_EQ(part.at(x, y), need.at(x, y) ? full.at(x, y) : 0) << x << "," << y << " w" << win << " pct " << pct;
    }
  }
}

TEST(Esr, BothEntropyKernelsMatchTheReferenceOnOddSizes) {
  // The sorted kernel (5 x 5 blocks, 32 pixels at a time) and the sliding one against per-block
  // recomputation: widths below, at and across multiples of its 32 lanes, 1-4 rows (blocks clipped
  // above and below at once), invalid pixels, bins clamped at max_disparity, need masks, and
  // segment-like patches (long runs of equal bins: the sorted runs' positions reach 25). kSorted runs
  // its AVX-512BW or AVX2 build where the CPU has one (portable otherwise: aarch64, qemu), and
  // kSortedPortable the portable one everywhere.
  for (auto [w, h, maxd, invalid_pct, block] : {std::tuple{1, 1, 20, 0, 1}, {5, 2, 20, 10, 1}, {31, 3, 20, 10, 3},
                                                 {32, 4, 6, 20, 2}, {33, 17, 20, 5, 4}, {97, 23, 12, 10, 7},
                                                 {64, 9, 40, 60, 3}, {70, 13, 3, 0, 9}}) {
    for (const bool patches : {false, true}) {
      ImageI16 d = random_disp(w, h, 20, unsigned(w * 31 + h), invalid_pct, block);
      if (patches)
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) d.at(x, y) = d.at(x - x % 9, y - y % 6);
      std::mt19937 rng(unsigned(w + 7 * h));
      std::uniform_int_distribution<int> u(0, 99);
      ImageU8 need(w, h, 0);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) need.at(x, y) = u(rng) < 50 ? 1 : 0;
      for (const EntropyKernel k : {EntropyKernel::kSorted, EntropyKernel::kSortedPortable, EntropyKernel::kSliding,
                                    EntropyKernel::kAuto}) {
        const ImageI32 full = block_entropy(d, 5, maxd, nullptr, k), part = block_entropy(d, 5, maxd, &need, k);
        ImageI16 clamped = d;  // the reference clamps bins at max_disparity as both kernels do
        for (auto& v : clamped.data)
          if (v != kInvalidDisp && ((v + kDispScale / 2) >> kDispShift) > maxd) v = static_cast<std::int16_t>(maxd * kDispScale);
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            const std::int32_t want = entropy_reference(clamped, x, y, 5);
            ASSERT_EQ(full.at(x, y), want) << x << "," << y << " size " << w << "x" << h << " kernel " << int(k);
            ASSERT_EQ(part.at(x, y), need.at(x, y) ? want : 0) << x << "," << y << " kernel " << int(k);
          }
      }
    }
  }
}

TEST(Esr, RefinementIsTheSameWithEveryEntropyKernel) {
  // `[esr] kernel` picks how eq. (14) is computed, never what eq. (15) does with it: the refined map
  // and the replaced mask are identical for every kernel, on random maps of odd sizes with invalid pixels.
  for (auto [w, h] : {std::pair{37, 11}, {96, 33}, {5, 5}}) {
    const ImageI16 dl = random_disp(w, h, 30, unsigned(w * 7 + h), 15, 3);
    const ImageI16 dr = random_disp(w, h, 30, unsigned(w * 5 + h + 1), 5, 3);
    EsrParams p;
    ImageU8 rep_ref;
    p.kernel = EntropyKernel::kSliding;
    const ImageI16 ref = entropy_selective_refinement(dl, dr, p, 40, &rep_ref);
    if (w > 5) {
      ASSERT_GT(std::count(rep_ref.data.begin(), rep_ref.data.end(), 1), 0) << "eq. (15) replaced nothing";
    }
    for (const EntropyKernel k : {EntropyKernel::kAuto, EntropyKernel::kSorted, EntropyKernel::kSortedPortable}) {
      p.kernel = k;
      ImageU8 rep;
      const ImageI16 out = entropy_selective_refinement(dl, dr, p, 40, &rep);
      EXPECT_EQ(out.data, ref.data) << w << "x" << h << " kernel " << int(k);
      EXPECT_EQ(rep.data, rep_ref.data) << w << "x" << h << " kernel " << int(k);
    }
  }
}

TEST(Esr, EntropyOfKnownBlocks) {
  ImageI16 d(9, 9, static_cast<std::int16_t>(3 * kDispScale));
  EXPECT_EQ(block_entropy(d, 3, 8).at(4, 4), 0);  // constant block: 0 bit
  for (int x = 0; x < 9; x += 2)
    for (int y = 0; y < 9; ++y) d.at(x, y) = static_cast<std::int16_t>(5 * kDispScale);
  // 3x3 block centred on an odd column: 3 of 9 at 5, 6 of 9 at 3 -> H = 0.9183 bit.
  EXPECT_NEAR(block_entropy(d, 3, 8).at(3, 4) / 65536.0, 0.918296, 1e-4);
}

TEST(Esr, BlockMeanMatchesScalarReference) {
  // Every window the config allows (3-31: the multiply-by-reciprocal path up to 13, the division above),
  // and maps near the largest Q4 disparity (2047 px) where the reciprocal's bound is tightest.
  for (const int max_px : {30, 2047})
    for (int win = 3; win <= 31; win += 2) {
      const ImageI16 d = random_disp(41, 37, max_px, 9u + unsigned(win), 20, 5);
      const ImageI16 m = block_mean(d, win);
      const int rr = win / 2;
      for (int y = 0; y < 37; ++y)
        for (int x = 0; x < 41; ++x) {
          std::int64_t s = 0, n = 0;
          for (int yy = y - rr; yy <= y + rr; ++yy)
            for (int xx = x - rr; xx <= x + rr; ++xx)
              if (xx >= 0 && yy >= 0 && xx < 41 && yy < 37 && d.at(xx, yy) >= 0) { s += d.at(xx, yy); ++n; }
          ASSERT_EQ(m.at(x, y), n ? std::int16_t(std::floor(double(s) / double(n) + 0.5)) : kInvalidDisp)
              << "window " << win << " max " << max_px << " at " << x << "," << y;
        }
    }
}

TEST(Esr, ReplacesOnlyWhereEntropiesDiffer) {
  const ImageI16 l = random_disp(47, 21, 16, 11u, 10, 4), r = random_disp(47, 21, 16, 12u, 3, 6);
  EsrParams p;
  p.window = 5;
  p.tau = 0.4;
  ImageU8 replaced;
  const ImageI16 out = entropy_selective_refinement(l, r, p, 16, &replaced);
  const ImageI32 El = block_entropy(l, 5, 16), Er = block_entropy(r, 5, 16);
  const ImageI16 Ml = block_mean(l, 5), Mr = block_mean(r, 5);
  int n_replaced = 0;
  for (int y = 0; y < 21; ++y)
    for (int x = 0; x < 47; ++x) {
      const int d = l.at(x, y);
      std::int16_t want = static_cast<std::int16_t>(d);
      if (d >= 0) {
        const int xr = x - int(std::floor(d / 16.0 + 0.5));
        if (xr >= 0) {
          const double el = El.at(x, y) / 65536.0, er = Er.at(xr, y) / 65536.0;  // eq. (15)
          if (std::fabs(el - er) > 0.4 + 1e-9) want = el < er ? Ml.at(x, y) : Mr.at(xr, y);
        }
      }
      EXPECT_EQ(out.at(x, y), want);
      n_replaced += replaced.at(x, y);
    }
  EXPECT_GT(n_replaced, 0);
}

}  // namespace
}  // namespace fs
