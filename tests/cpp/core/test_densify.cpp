// Densification (speckle removal + 8-direction median fill) against plain brute-force references:
// a union-find labelling for the speckles and a per-pixel ray walk for the fill.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "config.hpp"
#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {
namespace {

// Piecewise-constant blocks of random size (like painted segments) with random holes.
ImageI16 blocky_disp(int w, int h, unsigned seed, int invalid_pct) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> ud(1, 60 * kDispScale), up(0, 99), len(1, 12);
  ImageI16 img(w, h, kInvalidDisp);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w;) {
      const int n = len(rng);
      const bool copy_up = y > 0 && up(rng) < 60;
      const std::int16_t v = up(rng) < invalid_pct ? kInvalidDisp : static_cast<std::int16_t>(ud(rng));
      for (int i = 0; i < n && x < w; ++i, ++x) img.at(x, y) = copy_up ? img.at(x, y - 1) : v;
    }
  return img;
}

int find(std::vector<int>& p, int a) {
  while (p[a] != a) a = p[a] = p[p[a]];
  return a;
}

ImageI16 speckles_reference(const ImageI16& d, int max_size, int max_diff_q4) {
  const int w = d.width, h = d.height;
  std::vector<int> parent(w * h);
  std::iota(parent.begin(), parent.end(), 0);
  auto ok = [&](int a, int b) {
    return d.data[a] != kInvalidDisp && d.data[b] != kInvalidDisp && std::abs(d.data[a] - d.data[b]) <= max_diff_q4;
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int p = y * w + x;
      if (x + 1 < w && ok(p, p + 1)) parent[find(parent, p)] = find(parent, p + 1);
      if (y + 1 < h && ok(p, p + w)) parent[find(parent, p)] = find(parent, p + w);
    }
  std::vector<int> size(w * h, 0);
  for (int p = 0; p < w * h; ++p)
    if (d.data[p] != kInvalidDisp) ++size[find(parent, p)];
  ImageI16 out = d;
  for (int p = 0; p < w * h; ++p)
    if (d.data[p] != kInvalidDisp && size[find(parent, p)] <= max_size) out.data[p] = kInvalidDisp;
  return out;
}

// interp_q4 > 0: opposite rays within interp_q4 both take their linear interpolation at the pixel.
ImageI16 fill_reference(const ImageI16& d, int interp_q4 = 0) {
  const int w = d.width, h = d.height;
  const int dirs[8][2] = {{0, 1}, {0, -1}, {1, 0}, {-1, 0}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};
  ImageI16 out = d;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (d.at(x, y) != kInvalidDisp) continue;
      std::vector<int> v;
      int ray[8], steps[8];
      for (int k = 0; k < 8; ++k) {
        ray[k] = kInvalidDisp;
        steps[k] = 0;
        for (int s = 1;; ++s) {  // walk against the direction
          const int yy = y - s * dirs[k][0], xx = x - s * dirs[k][1];
          if (yy < 0 || yy >= h || xx < 0 || xx >= w) break;
          if (d.at(xx, yy) != kInvalidDisp) {
            ray[k] = d.at(xx, yy);
            steps[k] = s;
            break;
          }
        }
      }
      int val[8];
      std::copy(ray, ray + 8, val);
      if (interp_q4 > 0) {
        const int pairs[4][2] = {{0, 1}, {2, 3}, {4, 7}, {5, 6}};  // opposite directions
        for (const auto& pr : pairs) {
          const int a = pr[0], b = pr[1];
          if (ray[a] == kInvalidDisp || ray[b] == kInvalidDisp || std::abs(ray[a] - ray[b]) > interp_q4) continue;
          // the line through (0, ray[a]) and (steps[a] + steps[b], ray[b]) at steps[a], rounded half up
          const int span = steps[a] + steps[b], num = ray[a] * span + (ray[b] - ray[a]) * steps[a];
          val[a] = val[b] = (2 * num + span) / (2 * span);
        }
      }
      for (int k = 0; k < 8; ++k)
        if (ray[k] != kInvalidDisp) v.push_back(val[k]);
      int r = kInvalidDisp;
      if (ray[0] == kInvalidDisp && ray[1] != kInvalidDisp) {
        r = ray[1];
      } else if (!v.empty()) {
        std::sort(v.begin(), v.end());
        const std::size_t m = v.size();
        r = (m % 2) ? v[m / 2] : (v[m / 2 - 1] + v[m / 2] + 1) / 2;
      }
      out.at(x, y) = static_cast<std::int16_t>(r);
    }
  return out;
}

// With 1 and 3 threads: the per-row run passes are split between threads.
TEST(Densify, SpecklesMatchUnionFindReference) {
  for (int threads : {1, 3})
  for (unsigned seed = 1; seed <= 6; ++seed) {
    detail::use_threads(threads);
    const int w = 37 + 2 * static_cast<int>(seed), h = 29 + static_cast<int>(seed);
    const ImageI16 d = blocky_disp(w, h, seed, 25);
    for (int size : {0, 1, 7, 40}) {
      ImageI16 a = d;
      ImageU8 removed(w, h, 0);
      const int n = remove_speckles(a, size, 2 * kDispScale, &removed);
      const ImageI16 ref = size > 0 ? speckles_reference(d, size, 2 * kDispScale) : d;
      ASSERT_EQ(a.data, ref.data) << "seed " << seed << " size " << size;
      int diff = 0;
      for (std::size_t i = 0; i < d.data.size(); ++i) diff += d.data[i] != a.data[i];
      EXPECT_EQ(n, diff);
      if (size == 40) {
        EXPECT_GT(n, 0) << "test image has no speckle; the check would be empty";
      }
    }
  }
  detail::use_threads(0);
}

// Two runs of consecutive rows whose overlap connects only at its last pixel (the row below ramps
// towards the row above): they form one component of 20 pixels, which stays at max_size 12; the two
// 10-pixel halves alone would go. Catches a join that looks at part of the overlap only.
TEST(Densify, SpecklesJoinWhereOnlyTheLastOverlapPixelConnects) {
  ImageI16 d(12, 3, kInvalidDisp);
  for (int x = 0; x < 10; ++x) {
    d.at(x, 0) = 100;
    d.at(x, 1) = static_cast<std::int16_t>(200 - 10 * x);  // steps of 10 <= 32; |d - 100| <= 32 only at x = 9
  }
  for (int threads : {1, 3}) {
    detail::use_threads(threads);
    ImageI16 a = d;
    ImageU8 removed(12, 3, 0);
    EXPECT_EQ(remove_speckles(a, 12, 2 * kDispScale, &removed), 0) << "threads " << threads;
    EXPECT_EQ(a.data, d.data);
    EXPECT_EQ(speckles_reference(d, 12, 2 * kDispScale).data, d.data);  // the reference agrees
  }
  detail::use_threads(0);
}

// The plain median fill (threshold 0) and the slant-aware fill (interpolate_max_diff, 3
// thresholds) against the per-pixel ray walk, with 1 and 3 threads (rows and ray planes are split
// between threads).
TEST(Densify, MedianFillMatchesRayWalkReference) {
  for (int threads : {1, 3}) {
    detail::use_threads(threads);
    for (unsigned seed = 11; seed <= 16; ++seed) {
      const int w = 41 + 2 * static_cast<int>(seed % 5), h = 23 + 2 * static_cast<int>(seed % 3);
      for (int pct : {10, 60, 95}) {
        const ImageI16 d = blocky_disp(w, h, seed * 7 + pct, pct);
        for (int tq4 : {0, 1, 8 * kDispScale, 64 * kDispScale}) {
          ImageU8 filled;
          const ImageI16 out = median_fill(d, &filled, tq4);
          ASSERT_EQ(out.data, fill_reference(d, tq4).data)
              << "seed " << seed << " invalid " << pct << "% threshold " << tq4 << " threads " << threads;
          for (std::size_t i = 0; i < d.data.size(); ++i)
            EXPECT_EQ(filled.data[i], d.data[i] == kInvalidDisp && out.data[i] != kInvalidDisp ? 1 : 0);
        }
      }
    }
  }
  detail::use_threads(0);
}

// A band of rows without estimates in a slanted plane (disparity growing down the rows, like a
// road): the plain median fill puts the mean of the rows above and below into the whole band (a
// step), the interpolating fill puts the plane.
TEST(Densify, InterpolationFillsASlantedPlaneExactly) {
  const int w = 61, h = 21;
  ImageI16 d(w, h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) d.at(x, y) = static_cast<std::int16_t>(160 + 16 * y);  // 10 px + 1 px per row
  for (int y = 5; y <= 15; ++y)
    for (int x = 0; x < w; ++x) d.at(x, y) = kInvalidDisp;  // rows 5..15: no horizontal ray
  const ImageI16 plain = median_fill(d, nullptr, 0), slant = median_fill(d, nullptr, 64 * kDispScale);
  int plain_off = 0;
  for (int y = 5; y <= 15; ++y)
    for (int x = 11; x < w - 11; ++x) {  // columns where every diagonal ray meets row 4 or 16
      EXPECT_EQ(slant.at(x, y), 160 + 16 * y) << x << "," << y;
      plain_off += std::abs(plain.at(x, y) - (160 + 16 * y)) > 16;
    }
  EXPECT_GT(plain_off, 0) << "the plain median fill already follows the slant; the test shows nothing";
  // Rows 4 and 16 differ by 12 px: with an 8 px threshold nothing is interpolated (= plain).
  EXPECT_EQ(median_fill(d, nullptr, 8 * kDispScale).data, plain.data);
}

// The interpolation's float quotient with its correction steps is the exact integer rounding even
// at the largest values and step counts: one row with estimates only at both ends, so every pixel
// between takes the left/right interpolation. The cases (a, b, steps to a, steps to b at the
// pixel checked) were found by a search where trunc(float(M) / float(d)) is one below (first three)
// or one above (last three) floor(M / d), so each correction step is needed.
TEST(Densify, InterpolationIsExactForLongRaysAndLargeValues) {
  struct Case {
    int a, b, ta, tb;
  };
  const Case cases[] = {{3023, 3196, 13695, 13695}, {3635, 4020, 6929, 19097}, {3668, 4095, 10630, 19134},
                        {2032, 2591, 1961, 9639},   {3452, 4001, 8969, 10455}, {2085, 2544, 6892, 2537}};
  for (const Case& c : cases) {
    const int w = c.ta + c.tb + 1;
    ImageI16 row(w, 1, kInvalidDisp);
    row.at(0, 0) = static_cast<std::int16_t>(c.a);
    row.at(w - 1, 0) = static_cast<std::int16_t>(c.b);
    const ImageI16 f = median_fill(row, nullptr, 64 * kDispScale);
    for (int x = 1; x < w - 1; ++x) {
      const std::int64_t ta = x, tb = w - 1 - x, span = ta + tb;
      const std::int64_t num = std::int64_t(c.a) * tb + std::int64_t(c.b) * ta;
      ASSERT_EQ(f.at(x, 0), (2 * num + span) / (2 * span)) << "x " << x << " a " << c.a << " b " << c.b;
    }
  }
}

TEST(Densify, AllInvalidStaysInvalidAndLeftBorderTakesRightNeighbour) {
  ImageI16 none(9, 5, kInvalidDisp);
  EXPECT_EQ(median_fill(none, nullptr).data, none.data);
  // One row: holes at the left border take the first estimate to their right, not a median.
  ImageI16 row(7, 1, kInvalidDisp);
  row.at(3, 0) = 80;
  row.at(6, 0) = 16;
  const ImageI16 f = median_fill(row, nullptr);
  EXPECT_EQ(f.at(0, 0), 80);
  EXPECT_EQ(f.at(2, 0), 80);
  EXPECT_EQ(f.at(4, 0), (16 + 80 + 1) / 2);  // two rays: mean of left (80) and right (16)
}

// Occlusion fill, per pixel: seen when some right pixel xr lands within `dilate` px
// (xr + round(d_r)); the run of holes found by walking left and right from the pixel.
ImageI16 occlusion_reference(const ImageI16& d, const ImageI16& r, int dilate, int max_gap) {
  const int w = d.width, h = d.height;
  ImageI16 out = d;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (d.at(x, y) != kInvalidDisp) continue;
      bool seen = false;
      for (int xr = 0; xr < w; ++xr) {
        const std::int16_t v = r.at(xr, y);
        if (v == kInvalidDisp) continue;
        const int lx = xr + static_cast<int>(std::lround(std::floor(v / 16.0 + 0.5)));
        if (lx >= 0 && lx < w && std::abs(lx - x) <= dilate) seen = true;
      }
      if (seen) continue;
      int a = x, b = x;
      while (a - 1 >= 0 && d.at(a - 1, y) == kInvalidDisp) --a;
      while (b + 1 < w && d.at(b + 1, y) == kInvalidDisp) ++b;
      if (b - a + 1 > max_gap) continue;
      const std::int16_t lv = a > 0 ? d.at(a - 1, y) : kInvalidDisp, rv = b + 1 < w ? d.at(b + 1, y) : kInvalidDisp;
      if (lv == kInvalidDisp && rv == kInvalidDisp) continue;
      out.at(x, y) = lv == kInvalidDisp ? rv : (rv == kInvalidDisp ? lv : std::min(lv, rv));
    }
  return out;
}

TEST(Densify, OcclusionFillMatchesPerPixelReference) {
  for (int threads : {1, 3}) {
    detail::use_threads(threads);
    for (unsigned seed = 21; seed <= 26; ++seed) {
      const int w = 47 + 2 * static_cast<int>(seed % 5), h = 13 + 2 * static_cast<int>(seed % 3);
      for (int pct : {10, 60}) {
        const ImageI16 d = blocky_disp(w, h, seed * 5 + pct, pct);
        const ImageI16 r = blocky_disp(w, h, seed * 3 + 1, 15);
        for (int dilate : {0, 1, 3})
          for (int gap : {1, 8, 4096}) {
            ImageI16 out = d;
            ImageU8 filled(w, h, 0);
            const int n = occlusion_fill(out, r, dilate, gap, &filled);
            ASSERT_EQ(out.data, occlusion_reference(d, r, dilate, gap).data)
                << "seed " << seed << " invalid " << pct << "% dilate " << dilate << " gap " << gap << " threads " << threads;
            int changed = 0;
            for (std::size_t i = 0; i < d.data.size(); ++i) {
              EXPECT_EQ(filled.data[i], out.data[i] != d.data[i] ? 1 : 0);
              changed += out.data[i] != d.data[i];
            }
            EXPECT_EQ(n, changed);
          }
      }
    }
  }
  detail::use_threads(0);
}

// Background 10 px, a box at 20 px over left columns 40..59 (right columns 20..39): left columns
// 30..39 see background the box hides from the right camera. Their holes take the background (the
// median fill alone would mix in the box); the seen holes beside them are left to the median fill.
TEST(Densify, OcclusionFillPutsTheBackgroundBesideANearerBox) {
  const int w = 80;
  ImageI16 left(w, 3, 10 * kDispScale), right(w, 3, 10 * kDispScale);
  for (int y = 0; y < 3; ++y) {
    for (int x = 40; x < 60; ++x) left.at(x, y) = 20 * kDispScale;
    for (int x = 20; x < 40; ++x) right.at(x, y) = 20 * kDispScale;
    for (int x = 28; x < 44; ++x) left.at(x, y) = kInvalidDisp;
  }
  ImageI16 out = left;
  EXPECT_EQ(occlusion_fill(out, right, 0, 64, nullptr), 3 * 10);
  for (int x = 30; x < 40; ++x) EXPECT_EQ(out.at(x, 1), 10 * kDispScale) << x;
  for (int x : {28, 29, 40, 43}) EXPECT_EQ(out.at(x, 1), kInvalidDisp) << x;
  ImageI16 gap_limited = left;
  EXPECT_EQ(occlusion_fill(gap_limited, right, 0, 15, nullptr), 0);  // the run is 16 px
  DensifyParams p;
  p.speckle_max_size = 0;
  p.occlusion_dilate = 0;
  p.smooth = false;  // the fill alone
  const ImageI16 dense = densify(left, p, nullptr, &right);
  for (int x = 30; x < 40; ++x) EXPECT_EQ(dense.at(x, 1), 10 * kDispScale) << x;
  EXPECT_THROW(densify(left, p, nullptr), std::invalid_argument);  // occlusion_fill needs the right map
  p.occlusion_fill = false;
  const ImageI16 plain = densify(left, p, nullptr);
  EXPECT_GT(plain.at(35, 1), 12 * kDispScale);  // the 8-ray median mixes in the box
  ImageI16 small(5, 3);
  EXPECT_THROW(occlusion_fill(small, right, 0, 64, nullptr), std::invalid_argument);
}

// Bilateral smoothing, per pixel and tap with explicit clamps, weights computed on the spot in
// double and rounded as the stage's tables are.
ImageI16 smooth_reference(const ImageI16& d, const SmoothParams& p) {
  const int w = d.width, h = d.height, r = (p.radius / p.step) * p.step;
  ImageI16 out(w, h, kInvalidDisp);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int c = d.at(x, y);
      if (c == kInvalidDisp) continue;
      std::int64_t num = 0, den = 0;
      for (int oy = -r; oy <= r; oy += p.step)
        for (int ox = -r; ox <= r; ox += p.step) {
          const int v = d.at(std::clamp(x + ox, 0, w - 1), std::clamp(y + oy, 0, h - 1));
          if (v == kInvalidDisp) continue;
          const auto ws = std::lround(std::exp(-(ox * ox + oy * oy) / (2.0 * p.sigma_space * p.sigma_space)) * 4096);
          // biweight: k = |delta| / (2 sigma(c)) in 1/128 steps (rounded, through the rounded reciprocal)
          const double sigma_q4 = std::max(p.sigma_range * 16, p.sigma_range_rel * c);
          const std::int64_t inv = std::lround(65536.0 * 128 / (2 * sigma_q4));
          const std::int64_t k = std::min<std::int64_t>((std::int64_t(std::min(std::abs(v - c), 4095)) * inv + 32768) >> 16, 128);
          const std::int64_t t = 4096 - k * k / 4;
          const std::int64_t wr = t * t / 4096;
          const std::int64_t wt = (ws * wr) >> 12;
          num += wt * v;
          den += wt;
        }
      out.at(x, y) = static_cast<std::int16_t>((2 * num + den) / (2 * den));
    }
  return out;
}

TEST(Densify, SmoothingMatchesPerPixelReference) {
  std::vector<SmoothParams> ps(4);
  ps[1].radius = 8, ps[1].step = 4, ps[1].sigma_range = 2.5, ps[1].sigma_range_rel = 0.0;
  ps[2].radius = 3, ps[2].step = 1, ps[2].sigma_space = 2.0, ps[2].sigma_range = 30.0;
  ps[3].sigma_range_rel = 0.5;
  ps[3].radius = 0;  // one tap: the map itself
  for (int threads : {1, 3}) {
    detail::use_threads(threads);
    for (unsigned seed = 31; seed <= 34; ++seed) {
      const int w = 29 + 2 * static_cast<int>(seed % 5), h = 17 + 2 * static_cast<int>(seed % 3);
      const ImageI16 d = blocky_disp(w, h, seed, 20);
      for (std::size_t i = 0; i < ps.size(); ++i)
        ASSERT_EQ(smooth_disparity(d, ps[i]).data, smooth_reference(d, ps[i]).data)
            << "seed " << seed << " params " << i << " threads " << threads;
      EXPECT_EQ(smooth_disparity(d, ps[3]).data, d.data);
    }
  }
  detail::use_threads(0);
  SmoothParams bad;
  bad.step = 0;
  EXPECT_THROW(smooth_disparity(ImageI16(4, 4, 16), bad), std::invalid_argument);
}

// A plane rising 1 px of disparity every 8 columns, painted as 8 px wide constant segments (the
// segment WTA's staircase), beside a box 30 px nearer: the smoothing brings the staircase to the
// plane and leaves the depth edge where it was.
TEST(Densify, SmoothingTurnsAStaircaseIntoTheSlopeAndKeepsDepthEdges) {
  const int w = 96, h = 24;
  ImageI16 stairs(w, h), plane(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      plane.at(x, y) = static_cast<std::int16_t>(20 * kDispScale + (x * kDispScale) / 8);
      stairs.at(x, y) = static_cast<std::int16_t>(20 * kDispScale + (x / 8) * kDispScale + kDispScale / 2 - 1);
      if (x >= 64) plane.at(x, y) = stairs.at(x, y) = 60 * kDispScale;  // the box
    }
  const ImageI16 s = smooth_disparity(stairs, SmoothParams{});
  double err_before = 0, err_after = 0;
  int n = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 8; x < 56; ++x, ++n) {
      err_before += std::abs(stairs.at(x, y) - plane.at(x, y));
      err_after += std::abs(s.at(x, y) - plane.at(x, y));
    }
  EXPECT_LT(err_after, 0.6 * err_before) << "mean |error| before " << err_before / n / 16 << " px, after " << err_after / n / 16;
  for (int y = 0; y < h; ++y) {
    EXPECT_EQ(s.at(70, y), 60 * kDispScale);  // the box is untouched
    EXPECT_LT(s.at(63, y), 30 * kDispScale);  // the plane next to the box does not take the box's disparity
  }
}

TEST(Densify, ZeroCountsAsNoEstimateAndDisabledFillKeepsHoles) {
  ImageI16 d(5, 3, 32);
  d.at(2, 1) = 0;
  DensifyParams p;
  p.speckle_max_size = 0;
  p.occlusion_fill = false;  // no right map here
  ImageU8 changed;
  const ImageI16 out = densify(d, p, &changed);
  EXPECT_EQ(out.at(2, 1), 32);
  EXPECT_EQ(changed.at(2, 1), 2);
  p.fill = false;
  EXPECT_EQ(densify(d, p, nullptr).at(2, 1), kInvalidDisp);
}

// Left border extrapolation (docs/algorithm.md 6f) against a double-precision least-squares fit:
// random rows with a border band, random estimates (some invalid) after it.
TEST(Densify, BorderExtrapolationMatchesLeastSquaresReference) {
  std::mt19937 rng(45);
  std::uniform_int_distribution<int> band(0, 60), val(0, 150 * kDispScale), pct(0, 99), slope(-40, 40);
  const int w = 173, h = 61, window = 23, cap = 127 * kDispScale;
  ImageI16 before(w, h, kInvalidDisp);
  for (int y = 0; y < h; ++y) {
    const int x0 = band(rng), v0 = val(rng), s = slope(rng);
    for (int x = x0; x < w; ++x)
      before.at(x, y) = (x > x0 && pct(rng) < 20) ? kInvalidDisp
                                                  : static_cast<std::int16_t>(std::clamp(v0 + s * (x - x0) / 4 + pct(rng) % 9 - 4, 0, 32767));
  }
  ImageI16 out = before;
  for (auto& v : out.data)
    if (v == kInvalidDisp) v = 7;  // stands for the median fill
  const ImageI16 filled = out;
  const int rows = extrapolate_left_border(out, before, window, cap);
  int expect_rows = 0;
  for (int y = 0; y < h; ++y) {
    int x0 = 0;
    while (x0 < w && before.at(x0, y) == kInvalidDisp) ++x0;
    std::vector<double> xs, ds;
    for (int x = x0; x < std::min(w, x0 + window); ++x)
      if (before.at(x, y) != kInvalidDisp) xs.push_back(x), ds.push_back(before.at(x, y));
    const double n = double(xs.size());
    bool extrapolated = false;
    double a = 0, b = 0;
    if (x0 > 0 && x0 < w && n >= std::max(3, window / 4)) {
      const double mx = std::accumulate(xs.begin(), xs.end(), 0.0) / n, md = std::accumulate(ds.begin(), ds.end(), 0.0) / n;
      double sxx = 0, sxd = 0;
      for (std::size_t i = 0; i < xs.size(); ++i) sxx += (xs[i] - mx) * (xs[i] - mx), sxd += (xs[i] - mx) * (ds[i] - md);
      b = sxd / sxx;
      a = md - b * mx;
      extrapolated = sxd < 0;
    }
    expect_rows += extrapolated;
    for (int x = 0; x < w; ++x) {
      if (x >= x0 || !extrapolated) {
        ASSERT_EQ(out.at(x, y), filled.at(x, y)) << x << "," << y;
        continue;
      }
      const double v = std::min(a + b * x, double(cap));
      ASSERT_LE(std::abs(out.at(x, y) - v), 0.5 + 1e-6) << x << "," << y;
    }
  }
  EXPECT_EQ(rows, expect_rows);
  EXPECT_GT(rows, 10);
  // the slope threshold: none of these rows rises by 50 px per column
  ImageI16 again = filled;
  EXPECT_EQ(extrapolate_left_border(again, before, window, cap, 50.0 * kDispScale), 0);
  EXPECT_EQ(again.data, filled.data);
}

TEST(Densify, BorderExtrapolationContinuesASurfaceRecedingFromTheLeftEdge) {
  // A near car side at the left edge: d = 140 - 0.25 x px; the matcher found it from x = 120 on only.
  ImageI16 d(300, 3, kInvalidDisp);
  for (int y = 0; y < 3; ++y)
    for (int x = 120; x < 300; ++x) d.at(x, y) = static_cast<std::int16_t>((140 * 4 - x) * kDispScale / 4);
  DensifyParams p;
  p.occlusion_fill = false;
  p.smooth = false;
  p.speckle_max_size = 0;
  const ImageI16 nearest = densify(d, p, nullptr);
  EXPECT_EQ(nearest.at(0, 1), d.at(120, 1));  // the nearest estimate: 110 px
  p.border_fit_px = 40;
  const ImageI16 fitted = densify(d, p, nullptr, nullptr, 160);
  EXPECT_EQ(fitted.at(0, 1), 140 * kDispScale);
  EXPECT_EQ(fitted.at(60, 1), 125 * kDispScale);
  EXPECT_EQ(densify(d, p, nullptr, nullptr, 130).at(0, 1), 129 * kDispScale);  // capped below the search range
}

TEST(Densify, ConfigSectionReachesTheParams) {
  const MatcherParams p = parse_matcher_config(
      "[densify]\nenabled = false\nspeckle_max_size = 7\ninterpolate_max_diff = 3\nocclusion_fill = false\nocclusion_dilate = 2\n"
      "occlusion_max_gap = 9\nborder_fit_px = 40\nborder_fit_min_slope = 0.1\n", "t.toml");
  EXPECT_EQ(p.densify.border_fit_px, 40);
  EXPECT_DOUBLE_EQ(p.densify.border_fit_min_slope, 0.1);
  EXPECT_THROW(parse_matcher_config("[densify]\nborder_fit_px = 257\n", "t.toml"), ConfigError);
  EXPECT_FALSE(p.densify.occlusion_fill);
  EXPECT_EQ(p.densify.occlusion_dilate, 2);
  EXPECT_EQ(p.densify.occlusion_max_gap, 9);
  EXPECT_THROW(parse_matcher_config("[densify]\nocclusion_dilate = 9\n", "t.toml"), ConfigError);
  EXPECT_THROW(parse_matcher_config("[densify]\nocclusion_max_gap = 0\n", "t.toml"), ConfigError);
  // more than 11 x 11 smoothing taps: both fields named
  try {
    parse_matcher_config("[densify]\nsmooth_radius = 36\nsmooth_step = 6\n", "t.toml");
    ADD_FAILURE() << "6 taps each side accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("densify.smooth_radius"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("densify.smooth_step"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(parse_matcher_config("[densify]\nsmooth_radius = 35\nsmooth_step = 7\n", "t.toml"));
  EXPECT_FALSE(p.densify.enabled);
  EXPECT_EQ(p.densify.speckle_max_size, 7);
  EXPECT_EQ(p.densify.interpolate_max_diff, 3);
  EXPECT_THROW(parse_matcher_config("[densify]\ninterpolate_max_diff = 65\n", "t.toml"), ConfigError);
  EXPECT_THROW(parse_matcher_config("[densify]\nspeckle_max_diff = -1\n", "t.toml"), ConfigError);
}

}  // namespace
}  // namespace fs
