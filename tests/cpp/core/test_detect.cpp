// Detection stages: fast kernels against the plain scalar references (detect_reference.hpp),
// bit-exactly, on noisy synthetic scenes of awkward sizes; the integer HSV against eq. (18)-(21)
// in floating point.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>

#include "detect_reference.hpp"
#include "detect_scene.hpp"
#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

struct Case {
  int w, h;
  unsigned seed;
  double noise, holes;
};

const Case kCases[] = {{131, 97, 1, 0.3, 0.05}, {77, 53, 2, 0.8, 0.2}, {160, 120, 3, 0.0, 0.0}};

test::Scene scene_for(const Case& c) {
  return test::make_scene(c.w, c.h,
                          {{c.w / 6, c.w / 6 + c.w / 5, 2.0, 0.5}, {c.w / 2, c.w / 2 + c.w / 4, 3.5, 0.3},
                           {c.w - 12, c.w - 3, 1.5, 0.8}},
                          c.seed, c.noise, c.holes);
}

void expect_same(const ImageU8& a, const ImageU8& b, const char* what) {
  ASSERT_EQ(a.width, b.width) << what;
  ASSERT_EQ(a.height, b.height) << what;
  std::size_t diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff += a.data[i] != b.data[i];
  EXPECT_EQ(diff, 0u) << what;
}

TEST(DetectStages, DisparityBinsIsTheLargestRoundedValidDisparityPlusOne) {
  // Maps with invalid pixels, other negative values (not estimates), values at a rounding half-step and
  // empty or all-invalid maps, against the definition.
  std::mt19937 rng(5u);
  for (int trial = 0; trial < 50; ++trial) {
    const int w = 1 + trial % 13, h = 1 + trial % 7;
    std::uniform_int_distribution<int> u(-40, 16 * (1 + trial));
    ImageI16 d(w, h);
    for (auto& q : d.data) q = trial % 10 == 0 ? kInvalidDisp : static_cast<std::int16_t>(u(rng));
    int want = 0;
    for (const std::int16_t q : d.data)
      if (q != kInvalidDisp && q >= 0) want = std::max(want, (q + kDispScale / 2) >> kDispShift);
    ASSERT_EQ(detect::disparity_bins(d), want + 1) << "trial " << trial;
  }
  EXPECT_EQ(detect::disparity_bins(ImageI16()), 1);
}

TEST(DetectStages, VDisparityMatchesReference) {
  for (const Case& c : kCases) {
    const auto s = scene_for(c);
    const int bins = detect::disparity_bins(s.disp);
    const ImageI32 fast = detect::v_disparity(s.disp, bins), ref = ref::v_disparity(s.disp, bins);
    EXPECT_EQ(fast.data, ref.data) << c.w << "x" << c.h;
    std::int64_t total = 0, valid = 0;
    for (auto v : fast.data) total += v;
    for (auto q : s.disp.data) valid += q != kInvalidDisp;
    EXPECT_EQ(total, valid);  // every valid pixel in exactly one cell
  }
}

TEST(DetectStages, RoadPixelsAndClosingMatchReference) {
  for (const Case& c : kCases) {
    const auto s = scene_for(c);
    DetectParams p;
    const int bins = detect::disparity_bins(s.disp);
    std::int64_t valid = 0;
    for (auto q : s.disp.data) valid += q != kInvalidDisp;
    const RoadLine line = detect::fit_road_line(detect::v_disparity(s.disp, bins), valid, p);
    ASSERT_TRUE(line.found) << c.w << "x" << c.h;
    const auto table = detect::road_line_table(line, c.h);
    const ImageU8 fast = detect::road_pixels(s.disp, table, p.road_tolerance_px);
    expect_same(fast, ref::road_pixels(s.disp, table, p.road_tolerance_px), "road pixels");
    for (int r : {0, 1, 2, 5}) expect_same(detect::close_mask(fast, r), ref::close_mask(fast, r), "closing");
    // Band widening with disparity: bit-exact, and it only ever adds pixels (the band is wider).
    for (double rel : {0.02, 0.1}) {
      const ImageU8 wide = detect::road_pixels(s.disp, table, p.road_tolerance_px, rel);
      expect_same(wide, ref::road_pixels(s.disp, table, p.road_tolerance_px, rel), "road pixels, relative band");
      std::size_t lost = 0, gained = 0;
      for (std::size_t i = 0; i < wide.size(); ++i) lost += fast.data[i] && !wide.data[i], gained += wide.data[i] && !fast.data[i];
      EXPECT_EQ(lost, 0u);
      if (c.noise > 0.5 && rel >= 0.1) {
        EXPECT_GT(gained, 0u) << c.w << "x" << c.h;
      }
    }
    // Road completion: bit-exact, and only invalid pixels change.
    const ImageU8 closed = detect::close_mask(fast, 2);
    for (int run : {0, 3, 16, 1000}) {
      const ImageU8 done = detect::complete_road(closed, s.disp, table, run);
      expect_same(done, ref::complete_road(closed, s.disp, table, run), "road completion");
      for (std::size_t i = 0; i < done.size(); ++i) {
        if (done.data[i] != closed.data[i]) {
          ASSERT_EQ(s.disp.data[i], kInvalidDisp);
        }
      }
    }
  }
}

TEST(DetectStages, RoadCompletionRuns) {
  // One row, line value present: road R, invalid -, other valid o.
  //   x: 0 1 2 3 4 5 6 7 8 9
  //      - - R - - R o - - R ... then an invalid run touching the right border after road.
  const int w = 14;
  ImageI16 d(w, 1, 100);
  ImageU8 road(w, 1, 0);
  for (int x : {0, 1, 3, 4, 7, 8, 11, 12, 13}) d.at(x, 0) = kInvalidDisp;
  for (int x : {2, 5, 9, 10}) road.at(x, 0) = 1;
  const std::vector<std::int32_t> line{100};
  const ImageU8 m = detect::complete_road(road, d, line, 2);
  const int expect[w] = {1, 1, 1, 1, 1, 1, 0, 0, 0, 1, 1, 0, 0, 0};  // 7-8: left neighbour o; 11-13: run of 3 > 2
  for (int x = 0; x < w; ++x) EXPECT_EQ(m.at(x, 0), expect[x]) << "x = " << x;
  EXPECT_EQ(detect::complete_road(road, d, line, 3).at(12, 0), 1);  // border run of 3 allowed at max_run 3
  EXPECT_EQ(detect::complete_road(road, d, {INT32_MIN}, 3).at(0, 0), 0);  // above the horizon: never
}

TEST(DetectStages, ClosingOnRandomMasks) {
  std::mt19937 rng(7);
  for (int it = 0; it < 20; ++it) {
    const int w = 1 + int(rng() % 40), h = 1 + int(rng() % 30), r = int(rng() % 6);
    ImageU8 m(w, h);
    for (auto& v : m.data) v = std::uint8_t(rng() % 3 != 0);
    expect_same(detect::close_mask(m, r), ref::close_mask(m, r), "random closing");
  }
}

TEST(DetectStages, HsvIntegerFollowsEquations18To21) {
  // A grid of colours (R, B every 3rd level, G every 5th: ~450k): integer result within rounding of the float
  // formula, and exact for S and V away from .5 ties.
  double worst_h = 0, worst_s = 0, worst_v = 0;
  for (int r = 0; r < 256; r += 3)
    for (int g = 0; g < 256; g += 5)
      for (int b = 0; b < 256; b += 3) {
        const double R = r / 255.0, G = g / 255.0, B = b / 255.0;  // eq. (18)
        const double cmax = std::max({R, G, B}), cmin = std::min({R, G, B}), dl = cmax - cmin;
        double H = 0;  // eq. (19)
        if (dl > 0) {
          if (cmax == R) H = 60.0 * std::fmod((G - B) / dl + 6.0, 6.0);
          else if (cmax == G) H = 60.0 * ((B - R) / dl + 2.0);
          else H = 60.0 * ((R - G) / dl + 4.0);
        }
        const double S = cmax == 0 ? 0 : dl / cmax * 100.0, V = cmax * 100.0;  // eq. (20), (21)
        const detect::Hsv hi = detect::rgb_to_hsv({std::uint8_t(r), std::uint8_t(g), std::uint8_t(b)});
        ASSERT_GE(hi.h, 0);
        ASSERT_LE(hi.h, 359);
        const double dh = std::min(std::fabs(hi.h - H), 360.0 - std::fabs(hi.h - H));
        worst_h = std::max(worst_h, dh);
        worst_s = std::max(worst_s, std::fabs(hi.s - S));
        worst_v = std::max(worst_v, std::fabs(hi.v - V));
      }
  EXPECT_LE(worst_h, 0.5 + 1e-9);  // rounding to the nearest integer only
  EXPECT_LE(worst_s, 0.5 + 1e-9);
  EXPECT_LE(worst_v, 0.5 + 1e-9);
  EXPECT_GT(worst_h, 0.4);  // and the integers are rounded, not truncated or exact by accident
  EXPECT_EQ(detect::rgb_to_hsv({255, 0, 0}).h, 0);
  EXPECT_EQ(detect::rgb_to_hsv({0, 255, 0}).h, 120);
  EXPECT_EQ(detect::rgb_to_hsv({0, 0, 255}).h, 240);
  EXPECT_EQ(detect::rgb_to_hsv({255, 0, 10}).h, 358);  // -2.35 deg -> -2 -> mod 360 (eq. 19's mod 6)
}

TEST(DetectStages, SkyMaskMatchesReference) {
  for (const Case& c : kCases) {
    auto s = scene_for(c);
    std::mt19937 rng(c.seed);
    for (std::size_t i = 0; i < s.rgb.size(); i += 3)  // random colours in a third of the pixels
      s.rgb.data[i] = {std::uint8_t(rng()), std::uint8_t(rng()), std::uint8_t(rng())};
    for (double maxd : {0.0, 2.0})
      for (double tex : {0.0, 6.0, 20.0}) {
        DetectParams p;
        p.sky_max_disparity_px = maxd;
        p.sky_max_texture = tex;  // session 8 texture test
        for (int rows : {0, c.h / 3, c.h})
          expect_same(detect::sky_mask(s.rgb, s.disp, rows, p), ref::sky_mask(s.rgb, s.disp, rows, p), "sky");
      }
  }
}

TEST(DetectStages, KMeansMatchesReference) {
  for (const Case& c : kCases) {
    const auto s = scene_for(c);
    ImageU8 cand(c.w, c.h);
    for (std::size_t i = 0; i < cand.size(); ++i) cand.data[i] = s.disp.data[i] >= 16 && (i % 7 != 0);
    for (int k : {1, 3, 6, 16})
    for (int merge : {0, 16, 40}) {
      const auto f = detect::kmeans_disparity(s.disp, cand, k, 30, merge), r = ref::kmeans(s.disp, cand, k, 30, merge);
      EXPECT_EQ(f.centres_q4, r.centres_q4) << "k=" << k;
      EXPECT_EQ(f.sizes, r.sizes) << "k=" << k;
      EXPECT_EQ(f.iterations, r.iterations) << "k=" << k;
      expect_same(f.labels, r.labels, "kmeans labels");
      EXPECT_TRUE(std::is_sorted(f.centres_q4.rbegin(), f.centres_q4.rend()));  // nearest first
      for (std::size_t i = 1; merge > 0 && i < f.centres_q4.size(); ++i) EXPECT_GE(f.centres_q4[i - 1] - f.centres_q4[i], 1);
    }
    // Iteration cap honoured.
    EXPECT_LE(detect::kmeans_disparity(s.disp, cand, 6, 1).iterations, 1);
  }
}

TEST(DetectStages, UDisparityMatchesReference) {
  for (const Case& c : kCases) {
    const auto s = scene_for(c);
    ImageU8 cand(c.w, c.h);
    for (std::size_t i = 0; i < cand.size(); ++i) cand.data[i] = s.disp.data[i] >= 16;
    const auto km = detect::kmeans_disparity(s.disp, cand, 6, 30);
    const int bins = detect::disparity_bins(s.disp), k = int(km.centres_q4.size());
    detect::UDispScratch scratch;  // reused across calls of different sizes, as the Detector does
    for (int t : {0, 1, 2}) {
      DetectParams p;
      p.udisp_d_tolerance_px = t;
      p.udisp_min_height_px = 4;
      p.udisp_min_run_px = 3;
      const auto f = detect::u_disparity_filter(s.disp, km.labels, k, bins, p, &scratch);
      const auto r = ref::u_disparity(s.disp, km.labels, k, bins, p);
      ASSERT_EQ(f.kept_cells.size(), r.kept_cells.size());
      for (std::size_t i = 0; i < f.kept_cells.size(); ++i) expect_same(f.kept_cells[i], r.kept_cells[i], "cells");
      expect_same(f.kept, r.kept, "kept pixels");
    }
  }
}

TEST(DetectStages, RelativeStepSeparatesFarNeighbours) {
  // Two touching surfaces at 6.7 px and 5.7 px (7.5 m and 8.9 m on the robot): 1 px apart, so the
  // absolute 1-px step joins them; 3 % of 6.7 px = 0.2 px does not (floor 0.25 px).
  ImageU8 m(20, 6, 1);
  ImageI16 d(20, 6);
  for (int y = 0; y < 6; ++y)
    for (int x = 0; x < 20; ++x) d.at(x, y) = std::int16_t(x < 10 ? 107 : 91);
  int n = 0;
  detect::connected_components(m, d, 16, &n);
  EXPECT_EQ(n, 1);
  const ImageI32 l = detect::connected_components(m, d, 16, &n, 0.03, 4);
  EXPECT_EQ(n, 2);
  EXPECT_NE(l.at(9, 3), l.at(10, 3));
  // A 0.25-px step (the floor) still joins at any disparity.
  for (int x = 10; x < 20; ++x)
    for (int y = 0; y < 6; ++y) d.at(x, y) = 103;
  detect::connected_components(m, d, 16, &n, 0.03, 4);
  EXPECT_EQ(n, 1);
}

TEST(DetectStages, ComponentsMatchFloodFill) {
  std::mt19937 rng(11);
  for (int it = 0; it < 30; ++it) {
    const int w = 5 + int(rng() % 60), h = 5 + int(rng() % 40);
    ImageU8 m(w, h);
    ImageI16 d(w, h);
    for (std::size_t i = 0; i < m.size(); ++i) {
      m.data[i] = std::uint8_t(rng() % 5 < 3);
      d.data[i] = std::int16_t(rng() % 64);
    }
    for (int step : {0, 16, 64}) {
      int nf = 0, nr = 0;
      const ImageI32 f = detect::connected_components(m, d, step, &nf), r = ref::components(m, d, step, &nr);
      EXPECT_EQ(nf, nr);
      EXPECT_EQ(f.data, r.data) << w << "x" << h << " step " << step;
    }
    // Relative step: 3 % / 10 % of the larger disparity, floor 4 Q4 (0.25 px), absolute cap 16.
    for (double rel : {0.03, 0.1}) {
      int nf = 0, nr = 0;
      const ImageI32 f = detect::connected_components(m, d, 16, &nf, rel, 4), r = ref::components(m, d, 16, &nr, rel, 4);
      EXPECT_EQ(nf, nr);
      EXPECT_EQ(f.data, r.data) << w << "x" << h << " rel " << rel;
    }
  }
}

TEST(DetectStages, BimodalSplitMatchesReference) {
  // Random components of blobs at two or three depths with noise; the fast split against the
  // sorted-values reference, bit-exactly (labels and count), for several parameter sets.
  std::mt19937 rng(23);
  int split_seen = 0;
  for (int it = 0; it < 25; ++it) {
    const int w = 20 + int(rng() % 60), h = 10 + int(rng() % 30);
    ImageU8 m(w, h, 0);
    ImageI16 d(w, h, kInvalidDisp);
    const int depths[3] = {100 + int(rng() % 200), 100 + int(rng() % 200), 100 + int(rng() % 200)};
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        if (rng() % 8 == 0) continue;
        m.at(x, y) = 1;
        const int band = (x * 3) / w;  // three vertical bands, touching
        d.at(x, y) = std::int16_t(depths[band] + int(rng() % 9) - 4);
      }
    int n = 0;
    const ImageI32 comp = detect::connected_components(m, d, 4096, &n);  // everything joins
    for (auto [rel, valley, min_px, rounds] : {std::tuple{0.12, 0.1, 10, 2}, std::tuple{0.05, 0.3, 30, 1},
                                               std::tuple{0.3, 0.05, 5, 3}}) {
      int nf = 0, nr = 0;
      const ImageI32 f = detect::split_bimodal_components(comp, n, d, min_px, rel, valley, rounds, &nf);
      const ImageI32 r = ref::split_bimodal(comp, n, d, min_px, rel, valley, rounds, &nr);
      EXPECT_EQ(nf, nr) << it;
      EXPECT_EQ(f.data, r.data) << w << "x" << h << " it " << it;
      split_seen += nf > n;
    }
  }
  EXPECT_GT(split_seen, 10);  // the cases exercise splitting, not only "unchanged"
}

TEST(DetectStages, BimodalThresholdRules) {
  // Two modes at 160 and 200 Q4 (20 %), 300 pixels each: split at Otsu's threshold between them.
  std::vector<std::int32_t> h(61, 0);
  h[0] = 300, h[40] = 300;  // lo = 160
  const int t = detect::bimodal_threshold_q4(h, 160, 100, 0.12, 0.1);
  EXPECT_GT(t, 160);
  EXPECT_LE(t, 200);
  EXPECT_EQ(detect::bimodal_threshold_q4(h, 160, 100, 0.25, 0.1), -1);  // modes closer than 25 %
  EXPECT_EQ(detect::bimodal_threshold_q4(h, 160, 301, 0.12, 0.1), -1);  // a side below min_px
  // A flat histogram (a slanted surface): the valley holds ~25 % > 10 %, no split.
  std::vector<std::int32_t> flat(61, 10);
  EXPECT_EQ(detect::bimodal_threshold_q4(flat, 160, 100, 0.12, 0.1), -1);
  EXPECT_GE(detect::bimodal_threshold_q4(flat, 160, 100, 0.12, 0.3), 0);  // allowed with a 30 % valley
}

}  // namespace
}  // namespace fs
