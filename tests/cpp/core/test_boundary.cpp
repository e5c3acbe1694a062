// Segment-boundary refinement (docs/algorithm.md 4b): the census transform and the per-segment
// summed-area implementation against plain per-pixel scalar references, and what the stage is for
// (a segment that straddles a depth edge gives its far-side pixels back to the other surface).
#include <algorithm>
#include <bit>
#include <cstdlib>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

#include "fuzzystereo/stages.hpp"
#include "test_util.hpp"

namespace fs {
namespace {

// ---- scalar references -------------------------------------------------------------------------

ImageU32 census_reference(const ImageU8& img, int radius) {
  const int w = img.width, h = img.height;
  ImageU32 out(w, h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint32_t code = 0;
      int bit = 0;
      for (int dy = -radius; dy <= radius; ++dy)
        for (int dx = -radius; dx <= radius; ++dx) {
          if (dx == 0 && dy == 0) continue;
          const int v = img.at(std::clamp(x + dx, 0, w - 1), std::clamp(y + dy, 0, h - 1));
          if (v < img.at(x, y)) code |= 1u << bit;
          ++bit;
        }
      out.at(x, y) = code;
    }
  return out;
}

int round_px(int d_q4) { return (d_q4 + kDispScale / 2) >> kDispShift; }

// Window cost of pixel (x0, y0) at integer disparity d, pixel by pixel, as the header states it.
int window_cost_reference(const ImageU32& a, const ImageU32& b, int x0, int y0, int d, int direction, int r,
                          int bits) {
  const int w = a.width, h = a.height;
  int sum = 0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const int x = std::clamp(x0 + dx, 0, w - 1), y = std::clamp(y0 + dy, 0, h - 1);
      const int xo = x - direction * d;
      sum += (xo < 0 || xo >= w) ? bits : std::popcount(a.at(x, y) ^ b.at(xo, y));
    }
  return sum;
}

ImageI16 refine_reference(const ImageI16& disp, const ImageU32& cref, const ImageU32& cother, int direction,
                          const BoundaryParams& p, int bits) {
  const int w = disp.width, h = disp.height, k = p.step, r = p.window / 2;
  const int margin = static_cast<int>(std::lround(p.margin * p.window * p.window));
  ImageI16 cur = disp;
  for (int pass = 0; pass < p.passes; ++pass) {
    ImageI16 next = cur;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const int d0 = cur.at(x, y);
        if (d0 == kInvalidDisp) continue;
        const int offs[8][2] = {{-k, 0}, {k, 0}, {0, -k}, {0, k}, {-2 * k, 0}, {2 * k, 0}, {0, -2 * k}, {0, 2 * k}};
        std::vector<int> cand;
        for (const auto& o : offs) {
          const int v = cur.at(std::clamp(x + o[0], 0, w - 1), std::clamp(y + o[1], 0, h - 1));
          if (v == kInvalidDisp || std::abs(v - d0) < p.min_jump * kDispScale) continue;
          if (std::none_of(cand.begin(), cand.end(), [&](int c) { return round_px(c) == round_px(v); }))
            cand.push_back(v);
        }
        if (cand.empty()) continue;
        int best = window_cost_reference(cref, cother, x, y, round_px(d0), direction, r, bits) - margin;
        int best_d = d0;
        for (const int c : cand) {
          const int cost = window_cost_reference(cref, cother, x, y, round_px(c), direction, r, bits);
          if (cost < best) best = cost, best_d = c;
        }
        next.at(x, y) = static_cast<std::int16_t>(best_d);
      }
    cur = next;
  }
  return cur;
}

// A WTA-like map: every segment painted with one random Q4 disparity (some left invalid).
ImageI16 painted_map(const Segmentation& seg, int D, unsigned seed, int invalid_pct) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> ud(0, (D - 1) * kDispScale), up(0, 99);
  std::vector<std::int16_t> v(std::size_t(seg.count));
  for (auto& d : v) d = up(rng) < invalid_pct ? kInvalidDisp : static_cast<std::int16_t>(ud(rng));
  return paint_segments(seg, v);
}

TEST(Boundary, CensusMatchesScalarReference) {
  for (const auto& [w, h, r] : {std::tuple{1, 1, 1}, {2, 3, 2}, {37, 23, 1}, {61, 29, 2}, {5, 40, 2}}) {
    const ImageU8 img = test::texture_image(w, h, static_cast<unsigned>(w * 7 + h + r));
    const ImageU32 got = census_transform(img, r);
    EXPECT_EQ(got.data, census_reference(img, r).data) << w << "x" << h << " r " << r;
  }
}

TEST(Boundary, CensusRejectsARadiusItsCodeCannotHold) {
  const ImageU8 img = test::texture_image(9, 9, 3);
  EXPECT_THROW(census_transform(img, 3), std::invalid_argument);
  EXPECT_THROW(census_transform(img, 0), std::invalid_argument);
}

TEST(Boundary, RefinementMatchesScalarReferenceOnRandomImages) {
  struct Case {
    int w, h, window, step, min_jump, passes;
    double margin;
    int direction, radius;
  };
  const Case cases[] = {
      {53, 31, 7, 4, 1, 1, 1.0, +1, 2}, {53, 31, 7, 4, 1, 1, 1.0, -1, 2}, {41, 27, 5, 4, 2, 1, 0.0, +1, 2},
      {67, 35, 3, 2, 1, 2, 0.5, -1, 1}, {29, 45, 1, 3, 3, 1, 2.0, +1, 2}, {79, 23, 9, 6, 1, 2, 1.5, +1, 2},
      {13, 11, 7, 4, 1, 1, 1.0, -1, 2},
      // larger images: many segments, candidates from several neighbours, two passes
      {150, 77, 7, 4, 1, 1, 1.0, +1, 2}, {131, 70, 5, 4, 2, 2, 1.0, -1, 2},
  };
  // Wide images with larger disparities and segments of several sizes: most segments take the
  // implementation's lane path (16-column chunks, docs/algorithm.md 4b), whose boxes span one to
  // several chunks and whose partners leave the other image near its border; the map also carries
  // per-pixel deviations from the segment's value (as a second pass sees it).
  struct WideCase {
    int w, h, region, D, window, direction, passes, noise_pct;
  };
  const WideCase wide[] = {
      {301, 61, 6, 40, 7, +1, 1, 0}, {301, 61, 6, 40, 7, -1, 1, 0},  {263, 53, 14, 60, 5, +1, 1, 15},
      {263, 53, 14, 60, 9, -1, 2, 15}, {257, 47, 9, 24, 3, +1, 1, 30}, {257, 47, 22, 90, 7, -1, 1, 5},
  };
  int switched_total = 0;
  for (const Case& c : cases) {
    const unsigned seed = static_cast<unsigned>(c.w * 31 + c.h + c.window);
    const ImageU8 left = test::texture_image(c.w, c.h, seed), right = test::texture_image(c.w, c.h, seed + 1);
    SegmentationParams sp;
    sp.region_size = 6;
    const Segmentation seg = slic_segment(left, sp);
    const ImageI16 disp = painted_map(seg, 12, seed + 2, 10);
    BoundaryParams p;
    p.enabled = true, p.census_radius = c.radius, p.window = c.window, p.step = c.step, p.min_jump = c.min_jump;
    p.passes = c.passes, p.margin = c.margin;
    const int bits = (2 * c.radius + 1) * (2 * c.radius + 1) - 1;
    const ImageU32 cl = census_transform(left, c.radius), cr = census_transform(right, c.radius);
    ImageU8 switched;
    const ImageI16 got = refine_boundaries(disp, seg, cl, cr, c.direction, p, &switched);
    const ImageI16 want = refine_reference(disp, cl, cr, c.direction, p, bits);
    EXPECT_EQ(got.data, want.data) << c.w << "x" << c.h << " window " << c.window << " direction " << c.direction;
    for (std::size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(switched.data[i], got.data[i] != disp.data[i] ? 1 : 0);
      switched_total += switched.data[i];
    }
  }
  EXPECT_GT(switched_total, 100);  // the cases exercise the switch, not only "nothing to do"
  int wide_switched = 0;
  for (const WideCase& c : wide) {
    const unsigned seed = static_cast<unsigned>(c.w * 17 + c.h + c.region + c.window);
    const ImageU8 left = test::texture_image(c.w, c.h, seed), right = test::texture_image(c.w, c.h, seed + 1);
    SegmentationParams sp;
    sp.region_size = c.region;
    const Segmentation seg = slic_segment(left, sp);
    ImageI16 disp = painted_map(seg, c.D, seed + 2, 5);
    std::mt19937 rng(seed + 3);
    std::uniform_int_distribution<int> up(0, 99), ud(0, (c.D - 1) * kDispScale);
    for (auto& v : disp.data)
      if (up(rng) < c.noise_pct) v = up(rng) < 10 ? kInvalidDisp : static_cast<std::int16_t>(ud(rng));
    BoundaryParams p;
    p.enabled = true, p.window = c.window, p.passes = c.passes;
    const ImageU32 cl = census_transform(left, 2), cr = census_transform(right, 2);
    ImageU8 switched;
    const ImageI16 got = refine_boundaries(disp, seg, cl, cr, c.direction, p, &switched);
    const ImageI16 want = refine_reference(disp, cl, cr, c.direction, p, 24);
    EXPECT_EQ(got.data, want.data) << c.w << "x" << c.h << " region " << c.region << " window " << c.window;
    p.bit_count = BitCount::kPortable;  // the portable bit count too (the CPU's vector one above)
    EXPECT_EQ(refine_boundaries(disp, seg, cl, cr, c.direction, p, nullptr).data, want.data)
        << "portable count, " << c.w << "x" << c.h << " region " << c.region << " window " << c.window;
    for (const auto v : switched.data) wide_switched += v;
  }
  EXPECT_GT(wide_switched, 1000);
}

// A textured background at 4 px and a textured square at 12 px. The WTA map gives the square's
// segment 5 background columns to its right (as a segment straddling the edge would); those
// columns are seen by both cameras, so their census cost is lower at the background's disparity.
TEST(Boundary, GivesAStraddlingSegmentsFarSidePixelsBackToTheBackground) {
  const int w = 96, h = 64, db = 4, df = 12;
  const int sx0 = 40, sx1 = 60, sy0 = 20, sy1 = 44, strip = 5;  // square [sx0, sx1) x [sy0, sy1)
  const ImageU8 bg = test::random_image(w + 32, h, 5), fg = test::random_image(w + 32, h, 6);
  ImageU8 left(w, h), right(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool in_l = y >= sy0 && y < sy1 && x >= sx0 && x < sx1;
      left.at(x, y) = in_l ? fg.at(x, y) : bg.at(x, y);
      // Right image: pixel xr shows the left pixel xr + d of whichever surface is in front there.
      const bool in_r = y >= sy0 && y < sy1 && x + df >= sx0 && x + df < sx1;
      right.at(x, y) = in_r ? fg.at(x + df, y) : bg.at(x + db, y);
    }
  ImageI32 labels(w, h, 0);
  ImageI16 disp(w, h, static_cast<std::int16_t>(db * kDispScale));
  for (int y = sy0; y < sy1; ++y)
    for (int x = sx0; x < sx1 + strip; ++x) labels.at(x, y) = 1, disp.at(x, y) = static_cast<std::int16_t>(df * kDispScale);
  const Segmentation seg = segmentation_from_labels(labels);
  BoundaryParams p;
  p.enabled = true, p.window = 7, p.margin = 1.0, p.step = 4, p.min_jump = 1;
  const ImageU32 cl = census_transform(left, 2), cr = census_transform(right, 2);
  const ImageI16 out = refine_boundaries(disp, seg, cl, cr, +1, p, nullptr);
  // The strip's columns beyond the first two (whose windows still hold mostly square pixels) go
  // back to the background; the square's own pixels stay.
  int col_back[strip] = {}, rows = 0, square_kept = 0, square_n = 0;
  for (int y = sy0 + 3; y < sy1 - 3; ++y, ++rows) {
    for (int i = 0; i < strip; ++i) col_back[i] += out.at(sx1 + i, y) == db * kDispScale;
    for (int x = sx0 + 3; x < sx1 - 3; ++x, ++square_n) square_kept += out.at(x, y) == df * kDispScale;
  }
  for (int i = 2; i < strip; ++i) EXPECT_EQ(col_back[i], rows) << "strip column " << i;
  EXPECT_GE(col_back[0] + col_back[1], rows) << col_back[0] << " + " << col_back[1] << " of 2 x " << rows;
  EXPECT_EQ(square_kept, square_n);
  // Without the stage's trigger (every candidate too close), nothing changes.
  p.min_jump = 16;
  EXPECT_EQ(refine_boundaries(disp, seg, cl, cr, +1, p, nullptr).data, disp.data);
}

}  // namespace
}  // namespace fs
