// Noise-triggered pre-smoothing (docs/algorithm.md 2c): binomial filter against a plain 2-D
// convolution, the noise estimate against images of known noise, and the matcher's trigger.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>

#include "config.hpp"
#include "fuzzystereo/matcher.hpp"
#include "fuzzystereo/stages.hpp"
#include "test_util.hpp"

namespace fs {
namespace {

// Plain scalar reference: 3x3 kernel [1 2 1]^T [1 2 1], replicated border, (sum + 8) / 16.
ImageU8 binomial_reference(const ImageU8& img) {
  ImageU8 out(img.width, img.height);
  auto px = [&](int x, int y) {
    return static_cast<int>(img.at(std::clamp(x, 0, img.width - 1), std::clamp(y, 0, img.height - 1)));
  };
  const int k[3] = {1, 2, 1};
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      int s = 0;
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) s += k[j + 1] * k[i + 1] * px(x + i, y + j);
      out.at(x, y) = static_cast<std::uint8_t>((s + 8) / 16);
    }
  return out;
}

// A smooth image (a slow ramp plus a large disc, i.e. edges but no fine texture) with white
// Gaussian noise of std sigma, rounded and clamped to 0..255.
ImageU8 noisy_scene(int w, int h, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  ImageU8 img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double v = 60.0 + 100.0 * x / w + 20.0 * y / h;
      if ((x - w / 2) * (x - w / 2) + (y - h / 2) * (y - h / 2) < (h / 3) * (h / 3)) v += 50.0;
      img.at(x, y) = static_cast<std::uint8_t>(std::clamp(std::lround(v + (sigma > 0 ? n(rng) : 0.0)), 0L, 255L));
    }
  return img;
}

TEST(Prefilter, BinomialMatchesScalarReferenceOnOddSizes) {
  for (auto [w, h] : {std::pair{37, 23}, {1, 1}, {2, 5}, {131, 7}, {5, 1}}) {
    const ImageU8 img = test::random_image(w, h, 3u + unsigned(w * h));
    EXPECT_EQ(binomial_smooth(img).data, binomial_reference(img).data) << w << "x" << h;
  }
}

TEST(Prefilter, NoiseEstimateFollowsTheAddedNoise) {
  // Smooth content estimates as (nearly) noise-free; added noise is recovered within 15 %.
  // (what is left is the 8-bit rounding of the ramp, std 1/sqrt(12) = 0.29 before the median)
  EXPECT_LT(estimate_noise_sigma(noisy_scene(201, 121, 0.0, 1)), 0.7);
  for (double sigma : {2.0, 4.0, 8.0}) {
    const double est = estimate_noise_sigma(noisy_scene(201, 121, sigma, 7));
    EXPECT_NEAR(est, sigma, 0.15 * sigma) << "sigma " << sigma;
  }
  // Tiny images: no interior, no estimate.
  EXPECT_EQ(estimate_noise_sigma(ImageU8(2, 9, 7)), 0.0);
}

TEST(Prefilter, BinomialPassDividesNoiseStd) {
  // One pass: white-noise std / 2.67 (sum of squared weights (6/16)^2); measured on the image
  // itself through the estimator, with a tolerance for rounding to 8 bits.
  const ImageU8 img = noisy_scene(301, 201, 8.0, 5);
  const double before = estimate_noise_sigma(img);
  const ImageU8 once = binomial_smooth(img);
  // The smoothed noise is no longer white; compare plain std of the difference to the clean scene.
  const ImageU8 clean = noisy_scene(301, 201, 0.0, 5);
  const ImageU8 clean_once = binomial_smooth(clean);
  double s0 = 0, s1 = 0;
  for (std::size_t i = 0; i < img.data.size(); ++i) {
    s0 += std::pow(double(img.data[i]) - clean.data[i], 2);
    s1 += std::pow(double(once.data[i]) - clean_once.data[i], 2);
  }
  const double ratio = std::sqrt(s0 / s1);
  EXPECT_NEAR(before, 8.0, 1.2);
  EXPECT_NEAR(ratio, 16.0 / 6.0, 0.35);
}

TEST(Prefilter, ExcessIgnoresGainAndAddsInQuadrature) {
  EXPECT_NEAR(noise_excess(3.0, 5.0, 100, 100), 4.0, 1e-12);
  EXPECT_NEAR(noise_excess(5.0, 3.0, 100, 100), 4.0, 1e-12);
  // A gain of 0.6 on the right scales its noise and its spread alike: no excess.
  EXPECT_NEAR(noise_excess(4.0, 2.4, 200, 120), 0.0, 1e-12);
  // Spread: q95 - q5 of a ramp 0..199 (one pixel per level) is 189 - 9 = 180.
  ImageU8 ramp(200, 1);
  for (int x = 0; x < 200; ++x) ramp.at(x, 0) = static_cast<std::uint8_t>(x);
  EXPECT_EQ(grey_spread(ramp), 180);
  EXPECT_EQ(grey_spread(ImageU8(5, 5, 9)), 1);
}

TEST(Prefilter, MatcherSmoothsOnlyPairsOfUnequalNoise) {
  const ImageU8 left = noisy_scene(96, 64, 0.0, 21);  // smooth content: texture would read as noise
  const ImageU8 right = test::shifted_right(left, 5);
  MatcherParams p = load_matcher_config("");
  p.cost.max_disparity = 16;
  p.cost.noise_excess = 2.0;
  const FisDefinition fis = load_fis_definition("");
  const Matcher m(p, fis);
  const MatchResult clean = m.match(left, right);
  EXPECT_FALSE(clean.noise_equalised);
  EXPECT_LT(clean.noise_excess, 1.0);
  // Equal noise: identical output to the stage switched off.
  MatcherParams off = p;
  off.cost.noise_excess = 0.0;
  EXPECT_EQ(Matcher(off, fis).match(left, right).disp_final.data, clean.disp_final.data);

  // Right image with noise of std 6: the pair is smoothed, and the matcher's input changes.
  ImageU8 noisy = right;
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0.0, 6.0);
  for (auto& v : noisy.data) v = static_cast<std::uint8_t>(std::clamp(std::lround(v + n(rng)), 0L, 255L));
  const MatchResult r = m.match(left, noisy);
  EXPECT_GT(r.noise_sigma_right, 4.5);
  EXPECT_GT(r.noise_excess, 2.0);
  EXPECT_TRUE(r.noise_equalised);
  EXPECT_NE(Matcher(off, fis).match(left, noisy).disp_final.data, r.disp_final.data);
  // ... and a darker copy (gain 0.6) of the clean right image is not taken for noise.
  ImageU8 dark = right;
  for (auto& v : dark.data) v = static_cast<std::uint8_t>(std::lround(v * 0.6));
  EXPECT_FALSE(m.match(left, dark).noise_equalised);
}

// docs/algorithm.md 4b "On a mismatched pair": with [boundary] enabled = false and on_mismatch = true the
// refinement runs exactly when noise equalisation or the grey-level gain trigger fires, and then gives
// the output of enabled = true; a matched pair gets the output of on_mismatch = false.
TEST(Prefilter, BoundaryRefinementRunsOnMismatchedPairsOnly) {
  const ImageU8 left = noisy_scene(96, 64, 0.0, 21);
  const ImageU8 right = test::shifted_right(left, 5);
  MatcherParams p = load_matcher_config("");
  p.cost.max_disparity = 16;
  p.cost.noise_excess = 2.0;
  ASSERT_FALSE(p.boundary.enabled);
  ASSERT_TRUE(p.boundary.on_mismatch);  // the default
  MatcherParams never = p, always = p;
  never.boundary.on_mismatch = false;
  always.boundary.enabled = true;
  const FisDefinition fis = load_fis_definition("");
  const Matcher m(p, fis), m_never(never, fis), m_always(always, fis);

  const MatchResult clean = m.match(left, right);
  EXPECT_FALSE(clean.boundary_refined);
  EXPECT_FALSE(clean.gain_triggered);
  EXPECT_EQ(m_never.match(left, right).disp_final.data, clean.disp_final.data);
  EXPECT_TRUE(m_always.match(left, right).boundary_refined);

  ImageU8 noisy = right;  // noise of std 6 on the right view: equalised, then refined
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0.0, 6.0);
  for (auto& v : noisy.data) v = static_cast<std::uint8_t>(std::clamp(std::lround(v + n(rng)), 0L, 255L));
  const MatchResult r = m.match(left, noisy);
  ASSERT_TRUE(r.noise_equalised);
  EXPECT_TRUE(r.boundary_refined);
  EXPECT_EQ(m_always.match(left, noisy).disp_final.data, r.disp_final.data);
  EXPECT_FALSE(m_never.match(left, noisy).boundary_refined);

  ImageU8 dark = right;  // gain 0.6: the grey-level trigger, then refined
  for (auto& v : dark.data) v = static_cast<std::uint8_t>(std::lround(v * 0.6));
  const MatchResult g = m.match(left, dark);
  EXPECT_FALSE(g.noise_equalised);
  EXPECT_TRUE(g.gain_triggered);
  EXPECT_TRUE(g.boundary_refined);
  EXPECT_EQ(m_always.match(left, dark).disp_final.data, g.disp_final.data);
}

}  // namespace
}  // namespace fs
