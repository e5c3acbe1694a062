#include <random>
// Data costs (eq. 1-9): the fast kernel (padded partner rows, prefix sums, SIMD loop over d,
// incremental entropies) against a plain per-(segment, d) scalar reference.
#include <algorithm>
#include <cmath>
#include <numeric>

#include <gtest/gtest.h>

#include "config.hpp"
#include "fuzzystereo/stages.hpp"
#include "test_util.hpp"

namespace fs {
namespace {

std::uint64_t isqrt(std::uint64_t v) {
  std::uint64_t r = 0;
  while ((r + 1) * (r + 1) <= v) ++r;
  return r;
}

// The reference's output: every cost dense, NMI where it was evaluated (nmi_valid).
struct RefCosts {
  int segments = 0, disparities = 0;
  std::vector<std::uint32_t> ncc, igsad, nmi;  // [s * D + d], Q16
  std::vector<std::uint8_t> nmi_valid;
};

// Integer reference: same formulas, computed the slow obvious way.
RefCosts reference_costs(const ImageU8& ref, const ImageU8& other, const ImageU16& rg, const ImageU16& og,
                             const Segmentation& seg, int dir, const CostParams& p, const FisLut& fis) {
  const int D = p.max_disparity, B = p.nmi_bins, w = ref.width;
  RefCosts c;
  c.segments = seg.count;
  c.disparities = D;
  const std::size_t total = std::size_t(seg.count) * std::size_t(D);
  c.ncc.assign(total, 0);
  c.igsad.assign(total, 0);
  c.nmi.assign(total, 0);
  c.nmi_valid.assign(total, 0);
  int maxn = *std::max_element(seg.pixels.begin(), seg.pixels.end());
  std::vector<std::uint64_t> T(std::size_t(maxn) + 1, 0);
  for (int k = 2; k <= maxn; ++k) T[std::size_t(k)] = std::uint64_t(std::llround(k * std::log2(double(k)) * 65536.0));
  auto entropy = [&](const std::vector<std::uint32_t>& hist, std::uint64_t n) -> std::uint64_t {
    std::uint64_t s = 0;
    for (auto v : hist) s += T[v];
    return T[n] > s ? (T[n] - s + n / 2) / n : 0;
  };
  for (int s = 0; s < seg.count; ++s) {
    std::vector<std::pair<int, int>> px;
    for (int y = 0; y < ref.height; ++y)
      for (int x = 0; x < w; ++x)
        if (seg.labels.at(x, y) == s) px.push_back({x, y});
    const auto n = std::int64_t(px.size());
    std::vector<std::int64_t> gsad(static_cast<std::size_t>(D));
    const std::size_t off = std::size_t(s) * std::size_t(D);
    std::int64_t sl = 0, sll = 0;
    for (auto [x, y] : px) { sl += ref.at(x, y); sll += ref.at(x, y) * ref.at(x, y); }
    const std::int64_t varl = n * sll - sl * sl;
    for (int d = 0; d < D; ++d) {
      std::int64_t sr = 0, srr = 0, slr = 0, g = 0;
      for (auto [x, y] : px) {
        const int xp = std::clamp(x - dir * (d + p.inject_shift), 0, w - 1);
        const std::int64_t l = ref.at(x, y), r = other.at(xp, y);
        sr += r; srr += r * r; slr += l * r;
        g += std::abs(int(rg.at(x, y)) - int(og.at(xp, y)));
      }
      gsad[std::size_t(d)] = g;
      const std::int64_t num0 = n * slr - sl * sr, varr = n * srr - sr * sr;
      std::uint32_t ncc = 0;
      if (num0 > 0 && varr > 0 && varl > 0) {
        const double q = double(num0) / std::sqrt(double(varl) * double(varr));
        ncc = q >= 1.0 ? 65536u : std::uint32_t(q * 65536.0 + 0.5);
      }
      c.ncc[off + std::size_t(d)] = ncc;
    }
    const std::int64_t gmax = *std::max_element(gsad.begin(), gsad.end());
    for (int d = 0; d < D; ++d)
      c.igsad[off + std::size_t(d)] =
          gmax > 0 ? std::uint32_t(65536 - std::int64_t(double(gsad[std::size_t(d)]) * (65536.0 / double(gmax)))) : 65536u;
    std::vector<int> order(static_cast<std::size_t>(D));
    std::iota(order.begin(), order.end(), 0);
    const int K = (p.nmi_candidates <= 0 || p.nmi_candidates >= D) ? D : p.nmi_candidates;
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
      return fis.lookup_nearest(c.ncc[off + std::size_t(a)], c.igsad[off + std::size_t(a)]) >
             fis.lookup_nearest(c.ncc[off + std::size_t(b)], c.igsad[off + std::size_t(b)]);
    });
    std::vector<std::uint32_t> hx(std::size_t(B), 0);
    for (auto [x, y] : px) ++hx[std::size_t(ref.at(x, y) * B / 256)];
    const std::uint64_t Hx = entropy(hx, std::uint64_t(n));
    for (int k = 0; k < K; ++k) {
      const int d = order[std::size_t(k)];
      std::vector<std::uint32_t> hy(std::size_t(B), 0), hxy(std::size_t(B * B), 0);
      for (auto [x, y] : px) {
        const int xp = std::clamp(x - dir * (d + p.inject_shift), 0, w - 1);
        const int bx = ref.at(x, y) * B / 256, by = other.at(xp, y) * B / 256;
        ++hy[std::size_t(by)];
        ++hxy[std::size_t(bx * B + by)];
      }
      const std::uint64_t Hy = entropy(hy, std::uint64_t(n)), Hxy = entropy(hxy, std::uint64_t(n));
      const std::uint64_t den = isqrt(Hx * Hy);
      std::uint32_t nmi = 0;
      if (den > 0 && Hx + Hy > Hxy) nmi = std::uint32_t(std::min<std::uint64_t>(((Hx + Hy - Hxy) << 16) / den, 65536));
      c.nmi[off + std::size_t(d)] = nmi;
      c.nmi_valid[off + std::size_t(d)] = 1;
    }
  }
  return c;
}

const FisLut& test_lut() {
  return *FisLut::cached(load_fis_definition(""), 257);
}

// The fast result against the reference: the dense NCC / IGSAD arrays are equal, and each segment's
// candidate records list, in ascending d, exactly the disparities the reference evaluated NMI for,
// with the reference's three costs.
void expect_same(const SegmentCosts& a, const RefCosts& b) {
  EXPECT_EQ(a.ncc, b.ncc);
  EXPECT_EQ(a.igsad, b.igsad);
  const int K = a.candidates_per_segment, D = b.disparities;
  ASSERT_EQ(a.candidates.size(), std::size_t(b.segments) * std::size_t(K));
  for (int s = 0; s < b.segments; ++s) {
    std::vector<std::int32_t> marked, listed;
    for (int d = 0; d < D; ++d)
      if (b.nmi_valid[std::size_t(s) * std::size_t(D) + std::size_t(d)]) marked.push_back(d);
    for (int k = 0; k < K; ++k) {
      const CostCandidate& r = a.candidates[std::size_t(s) * std::size_t(K) + std::size_t(k)];
      listed.push_back(r.d);
      const std::size_t i = std::size_t(s) * std::size_t(D) + std::size_t(r.d);
      ASSERT_EQ(r.ncc, b.ncc[i]) << "segment " << s << " d " << r.d;
      ASSERT_EQ(r.igsad, b.igsad[i]) << "segment " << s << " d " << r.d;
      ASSERT_EQ(r.nmi, b.nmi[i]) << "segment " << s << " d " << r.d;
    }
    ASSERT_EQ(listed, marked) << "segment " << s;
  }
}

TEST(SegmentCosts, BitExactAgainstScalarReference) {
  for (auto [w, h, D, K, dir] : {std::tuple{61, 29, 16, 4, +1}, {61, 29, 16, 4, -1}, {37, 13, 9, 0, +1},
                                 {45, 21, 23, 0, -1}, {33, 9, 40, 6, +1},
                                 // K = 8 with D >= 4K: the 16-lane residue maxima of top_k_threshold
                                 // (D = 70: four full rows and a tail of 6; D = 37: one row and 21)
                                 {83, 19, 70, 8, +1}, {59, 17, 37, 8, -1}}) {
    const ImageU8 l = test::texture_image(w, h, 21u), r = test::texture_image(w, h, 22u);
    const ImageU16 gl = gradient_magnitude(l), gr = gradient_magnitude(r);
    SegmentationParams sp;
    sp.region_size = 6;
    const Segmentation seg = slic_segment(dir > 0 ? l : r, sp);
    const auto& ref = dir > 0 ? l : r;
    const auto& oth = dir > 0 ? r : l;
    const auto& rg = dir > 0 ? gl : gr;
    const auto& og = dir > 0 ? gr : gl;
    for (int bins : {8, 16}) {  // 16 (the default): segments span more joint-histogram rows than pixels
      CostParams p;
      p.max_disparity = D;
      p.nmi_candidates = K;
      p.nmi_bins = bins;
      SCOPED_TRACE(::testing::Message() << w << "x" << h << " D=" << D << " K=" << K << " dir=" << dir << " B=" << bins);
      for (int threads : {1, 2})
        expect_same(compute_segment_costs(ref, oth, rg, og, seg, dir, p, test_lut(), threads),
                    reference_costs(ref, oth, rg, og, seg, dir, p, test_lut()));
    }
  }
}

// Segments larger than the int32 fast path (kFlushPixels = 32768 pixels: the int64 path with flushes)
// next to small ones whose pixel counts straddle the 45-pixel groups of the 16-bit kernel sums,
// on a bright high-contrast pair (largest products and gradient differences).
TEST(SegmentCosts, OversizedSegmentsUseTheExactWidePath) {
  const int w = 211, h = 181;  // 38191 pixels
  ImageU8 l(w, h), r(w, h);
  std::mt19937 rng(5u);
  std::uniform_int_distribution<int> u(0, 1);
  for (auto& v : l.data) v = static_cast<std::uint8_t>(u(rng) ? 255 : 200);
  for (auto& v : r.data) v = static_cast<std::uint8_t>(u(rng) ? 255 : 0);
  const ImageU16 gl = gradient_magnitude(l), gr = gradient_magnitude(r);
  ImageI32 labels(w, h, 0);  // segment 0: everything except a few small blocks
  int next = 1;
  for (int by = 0; by + 9 <= h; by += 40)
    for (int bx = 0; bx + 9 <= w; bx += 50, ++next)
      for (int y = by; y < by + 1 + next % 9; ++y)
        for (int x = bx; x < bx + 9; ++x) labels.at(x, y) = next;
  const Segmentation seg = segmentation_from_labels(labels);
  ASSERT_GT(seg.pixels[0], 32768);
  CostParams p;
  p.max_disparity = 37;
  p.nmi_candidates = 5;
  for (int dir : {+1, -1})
    expect_same(compute_segment_costs(dir > 0 ? l : r, dir > 0 ? r : l, dir > 0 ? gl : gr, dir > 0 ? gr : gl, seg, dir,
                                      p, test_lut(), 1),
                reference_costs(dir > 0 ? l : r, dir > 0 ? r : l, dir > 0 ? gl : gr, dir > 0 ? gr : gl, seg, dir, p,
                                test_lut()));
}

// The widest image the Matcher accepts at the largest D, partner rows all 255: the row prefix sums
// of the squared grey values pass 2^31 (W + D + 31 = 33054 partners of 65025); they are modular
// uint32, so the differences stay exact (a wrong wrap would fail here, a signed one under UBSan).
TEST(SegmentCosts, WidestRowsAtLargestRange) {
  const int w = kMaxImageWidth, h = 1;
  ImageU8 l(w, h), r(w, h);
  std::mt19937 rng(9u);
  std::uniform_int_distribution<int> u(240, 255);
  for (auto& v : l.data) v = static_cast<std::uint8_t>(u(rng));
  for (auto& v : r.data) v = 255;
  r.at(w / 2, 0) = 0;
  const ImageU16 gl = gradient_magnitude(l), gr = gradient_magnitude(r);
  SegmentationParams sp;
  sp.region_size = 16;
  const Segmentation seg = slic_segment(l, sp);
  CostParams p;
  p.max_disparity = 256;
  p.nmi_candidates = 4;
  expect_same(compute_segment_costs(l, r, gl, gr, seg, +1, p, test_lut(), 1),
              reference_costs(l, r, gl, gr, seg, +1, p, test_lut()));
}

TEST(SegmentCosts, InjectedShiftMovesThePartner) {
  const ImageU8 l = test::texture_image(40, 12, 1u), r = test::texture_image(40, 12, 2u);
  const ImageU16 gl = gradient_magnitude(l), gr = gradient_magnitude(r);
  SegmentationParams sp;
  sp.region_size = 6;
  const Segmentation seg = slic_segment(l, sp);
  CostParams p;
  p.max_disparity = 8;
  p.inject_shift = 1;
  expect_same(compute_segment_costs(l, r, gl, gr, seg, +1, p, test_lut(), 1), reference_costs(l, r, gl, gr, seg, +1, p, test_lut()));
}

TEST(SegmentCosts, FloatAgreementWithinDocumentedTolerance) {
  // Q16 NCC vs double NCC: |error| <= 2e-3 (isqrt of each variance separately).
  const ImageU8 l = test::texture_image(50, 20, 7u), r = test::texture_image(50, 20, 8u);
  const ImageU16 gl = gradient_magnitude(l), gr = gradient_magnitude(r);
  SegmentationParams sp;
  const Segmentation seg = slic_segment(l, sp);
  CostParams p;
  p.max_disparity = 10;
  const SegmentCosts c = compute_segment_costs(l, r, gl, gr, seg, +1, p, test_lut(), 1);
  for (int s = 0; s < seg.count; ++s)
    for (int d = 0; d < 10; ++d) {
      double sl = 0, sr = 0, sll = 0, srr = 0, slr = 0, n = 0;
      for (int y = 0; y < 20; ++y)
        for (int x = 0; x < 50; ++x) {
          if (seg.labels.at(x, y) != s) continue;
          const double a = l.at(x, y), b = r.at(std::max(0, x - d), y);
          sl += a; sr += b; sll += a * a; srr += b * b; slr += a * b; n += 1;
        }
      const double ncc = (slr - sl * sr / n) / std::sqrt((sll - sl * sl / n) * (srr - sr * sr / n));
      EXPECT_NEAR(c.ncc[std::size_t(s * 10 + d)] / 65536.0, std::clamp(ncc, 0.0, 1.0), 2e-3);
    }
}

TEST(SegmentCosts, TrueDisparityScoresBest) {
  const ImageU8 l = test::texture_image(80, 30, 4u);
  const ImageU8 r = test::shifted_right(l, 5);
  const ImageU16 gl = gradient_magnitude(l), gr = gradient_magnitude(r);
  SegmentationParams sp;
  const Segmentation seg = slic_segment(l, sp);
  CostParams p;
  p.max_disparity = 12;
  p.nmi_candidates = 0;
  const SegmentCosts c = compute_segment_costs(l, r, gl, gr, seg, +1, p, test_lut(), 1);
  int checked = 0;
  for (int s = 0; s < seg.count; ++s) {
    const fs::Run& first = seg.runs[std::size_t(seg.run_begin[std::size_t(s)])];
    if (first.x0 < 20) continue;  // left band: partners clamp at the border
    const std::size_t o = std::size_t(s) * 12;
    EXPECT_EQ(c.ncc[o + 5], 65536u);
    EXPECT_EQ(c.igsad[o + 5], 65536u);
    ASSERT_EQ(c.candidates_per_segment, 12);  // nmi_candidates = 0: every d, in order
    EXPECT_EQ(c.candidates[std::size_t(s) * 12 + 5].d, 5);
    EXPECT_EQ(c.candidates[std::size_t(s) * 12 + 5].nmi, 65536u);
    ++checked;
  }
  EXPECT_GT(checked, 10);
}

}  // namespace
}  // namespace fs
