#include <cmath>

#include <gtest/gtest.h>

#include <algorithm>
#include <tuple>
#include <vector>

#include "config.hpp"
#include "fuzzystereo/matcher.hpp"
#include "fuzzystereo/stages.hpp"
#include "test_util.hpp"

namespace fs {
namespace {

// Plain scalar reference of eq. (5): Sobel with replicated border, sqrt in double, rounded.
ImageU16 gradient_reference(const ImageU8& img) {
  ImageU16 out(img.width, img.height);
  auto px = [&](int x, int y) {
    x = std::clamp(x, 0, img.width - 1);
    y = std::clamp(y, 0, img.height - 1);
    return static_cast<int>(img.at(x, y));
  };
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const int kx[3][3] = {{-1, 0, 1}, {-2, 0, 2}, {-1, 0, 1}};
      int gx = 0, gy = 0;
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) {
          gx += kx[j + 1][i + 1] * px(x + i, y + j);
          gy += kx[i + 1][j + 1] * px(x + i, y + j);
        }
      out.at(x, y) = static_cast<std::uint16_t>(std::floor(std::sqrt(double(gx * gx + gy * gy)) + 0.5));
    }
  return out;
}

TEST(Gradient, MatchesScalarReferenceOnOddSizes) {
  for (auto [w, h] : {std::pair{37, 23}, {1, 1}, {2, 5}, {131, 7}}) {
    const ImageU8 img = test::random_image(w, h, 11u + unsigned(w));
    EXPECT_EQ(gradient_magnitude(img).data, gradient_reference(img).data) << w << "x" << h;
  }
}

// gradient_magnitude rounds sqrt in float (it vectorises twice as wide as double): for every
// possible v = gx^2 + gy^2 of 8-bit images (0 .. 2 * 1020^2) the float result must equal the exact
// round-half-up r(v) = floor(sqrt(v) + 1/2). Both are non-decreasing in v (a correctly rounded sqrt
// is monotone), so they agree everywhere when they agree on both sides of every step of r(v):
// r steps from k - 1 to k at the smallest v with 4 v >= (2k - 1)^2.
TEST(Gradient, FloatSqrtRoundsExactlyOverTheWholeRange) {
  const std::int64_t vmax = 2 * 1020 * 1020;
  auto f = [](std::int64_t v) { return static_cast<std::int64_t>(std::sqrt(static_cast<float>(v)) + 0.5f); };
  EXPECT_EQ(f(0), 0);
  for (std::int64_t k = 1;; ++k) {
    const std::int64_t b = ((2 * k - 1) * (2 * k - 1) + 3) / 4;  // ceil((2k - 1)^2 / 4)
    if (b > vmax) {
      EXPECT_EQ(f(vmax), k - 1);
      break;
    }
    EXPECT_EQ(f(b), k) << "v " << b;
    EXPECT_EQ(f(b - 1), k - 1) << "v " << b - 1;
  }
}

TEST(Gradient, MaximumIsBounded) {
  ImageU8 img(8, 8, 0);
  for (int y = 0; y < 8; ++y)
    for (int x = 4; x < 8; ++x) img.at(x, y) = 255;
  for (int y = 4; y < 8; ++y)
    for (int x = 0; x < 8; ++x) img.at(x, y) = 255;
  std::uint16_t m = 0;
  for (auto v : gradient_magnitude(img).data) m = std::max(m, v);
  EXPECT_LE(m, 1443);
  EXPECT_GT(m, 1000);
}

}  // namespace
}  // namespace fs

namespace fs {
namespace {
TEST(Gradient, DoubleSqrtRoundingIsExactOverTheWholeRange) {
  // Every v = gx^2 + gy^2 the Sobel can produce is below 2 * 1020^2 + 1.
  for (std::uint64_t v = 0; v <= 2u * 1020u * 1020u; ++v) {
    std::uint64_t r = 0;
    r = static_cast<std::uint64_t>(std::sqrt(double(v)));
    while (r * r > v) --r;
    while ((r + 1) * (r + 1) <= v) ++r;
    const std::uint64_t exact = (v - r * r > r) ? r + 1 : r;
    ASSERT_EQ(static_cast<std::uint64_t>(std::sqrt(static_cast<double>(v)) + 0.5), exact) << v;
  }
}
// Gain compensation (docs/algorithm.md 2b) against a plain per-pixel reference: a right image
// whose gradients are 0.6x the left's is scaled back; inside the dead band nothing changes.
TEST(Gradient, GainCompensationScalesTheOtherImageOutsideTheDeadBand) {
  const ImageU8 l = test::texture_image(53, 31, 4u);
  const ImageU16 gl = gradient_magnitude(l);
  ImageU16 dim = gl;
  for (auto& v : dim.data) v = static_cast<std::uint16_t>(v * 6 / 10);
  std::uint64_t sl = 0, sd = 0;
  for (auto v : gl.data) sl += v;
  for (auto v : dim.data) sd += v;
  ASSERT_GT(sd, 0u);
  const std::uint64_t f = ((sl << 16) + sd / 2) / sd;  // reference factor, Q16
  ImageU16 got = dim;
  EXPECT_EQ(compensate_gradient_gain(gl, got, 0.2), f);
  for (std::size_t i = 0; i < got.data.size(); ++i) {
    const std::uint64_t want = std::min<std::uint64_t>(1443, (dim.data[i] * f + 32768) >> 16);
    ASSERT_EQ(got.data[i], want) << "pixel " << i;
  }
  // The scaled image is back within 2 grey steps of the original gradients.
  for (std::size_t i = 0; i < got.data.size(); ++i) EXPECT_NEAR(got.data[i], gl.data[i], 2.0);
  // 0.6x is a 67 % difference: a dead band of 0.7 leaves it alone, and the reverse direction works.
  ImageU16 kept = dim;
  EXPECT_EQ(compensate_gradient_gain(gl, kept, 0.7), 65536u);
  EXPECT_EQ(kept.data, dim.data);
  ImageU16 bright = gl;
  EXPECT_LT(compensate_gradient_gain(dim, bright, 0.2), 65536u);
  // An all-zero image (flat) is left unchanged.
  ImageU16 flat(53, 31, 0);
  EXPECT_EQ(compensate_gradient_gain(gl, flat, 0.0), 65536u);
}
}  // namespace
}  // namespace fs

namespace fs {
namespace {

// grey_quantile_shift against sorting: quantile p = the sorted value at index ceil(p * N / 100) - 1.
double quantile_shift_reference(const ImageU8& a, const ImageU8& b) {
  auto q = [](const ImageU8& img, int p) {
    std::vector<std::uint8_t> v(img.data.begin(), img.data.end());
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size(), idx = (std::size_t(p) * n + 99) / 100 - 1;
    return int(v[idx]);
  };
  int s = 0;
  for (int p = 5; p <= 95; p += 5) s += std::abs(q(a, p) - q(b, p));
  return s / 19.0;
}

TEST(Gradient, GreyQuantileShiftMatchesSortingOnOddSizes) {
  for (auto [w, h, seed] : {std::tuple{17, 9, 1u}, {53, 31, 2u}, {1, 7, 3u}, {101, 3, 4u}}) {
    const ImageU8 a = test::texture_image(w, h, seed), b = test::random_image(w, h, seed + 10);
    EXPECT_DOUBLE_EQ(grey_quantile_shift(a, b), quantile_shift_reference(a, b)) << w << "x" << h;
    EXPECT_DOUBLE_EQ(grey_quantile_shift(a, a), 0.0);
  }
}

// The matcher's default trigger ("grey"): a right camera at 0.6x gain shifts the grey levels by far
// more than gradient_gain_grey_shift and its gradients are rescaled; the same camera pair without
// the gain (the right view is shifted content only) is left alone.
TEST(Gradient, GreyTriggerActsOnAGainNotOnContent) {
  const ImageU8 l = test::texture_image(96, 40, 5u), r = test::shifted_right(l, 4);
  ImageU8 dim = r;
  for (auto& v : dim.data) v = static_cast<std::uint8_t>((v * 6 + 5) / 10);
  MatcherParams p;
  p.cost.max_disparity = 16;
  ASSERT_EQ(p.cost.gradient_gain_trigger, GainTrigger::Grey);
  const Matcher m(p, load_fis_definition(""));
  const MatchResult clean = m.match(l, r), gain = m.match(l, dim);
  EXPECT_LT(clean.grey_quantile_shift, p.cost.gradient_gain_grey_shift);
  EXPECT_EQ(clean.gradient_gain_q16, 65536u);
  EXPECT_GT(gain.grey_quantile_shift, p.cost.gradient_gain_grey_shift);
  EXPECT_GT(gain.gradient_gain_q16, 65536u * 3 / 2);  // ~1/0.6
  // Trigger off: the same gain passes through unscaled.
  p.cost.gradient_gain_compensation = false;
  EXPECT_EQ(Matcher(p, load_fis_definition("")).match(l, dim).gradient_gain_q16, 65536u);
}

}  // namespace
}  // namespace fs
