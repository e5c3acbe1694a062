#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "config.hpp"
#include "fuzzystereo/fis.hpp"
#include "fuzzystereo/image.hpp"

namespace fs {
namespace {

const FisDefinition& def() {
  static const FisDefinition d = load_fis_definition("");
  return d;
}

TEST(FisDefinition, PaperTableOne) {
  const FisDefinition& d = def();
  EXPECT_EQ(d.in1.terms.size(), 6u);   // eq. (10)
  EXPECT_EQ(d.in2.terms.size(), 6u);   // eq. (11)
  EXPECT_EQ(d.out.terms.size(), 15u);  // eq. (12)
  ASSERT_EQ(d.rules.size(), 36u);      // Table I
  // The table prints a second "26"; it is rule 27: Good / Bad -> Acceptable.
  const FisRule& r27 = d.rules[26];
  EXPECT_EQ(r27.number, 27);
  EXPECT_EQ(d.in1.terms[std::size_t(r27.in1)].name, "good");
  EXPECT_EQ(d.in2.terms[std::size_t(r27.in2)].name, "bad");
  EXPECT_EQ(d.out.terms[std::size_t(r27.out)].name, "acceptable");
}

TEST(FisDefinition, MembershipsFormAPartition) {
  for (double x = 0.0; x <= 1.0; x += 0.013) {
    double s = 0;
    for (const auto& t : def().in1.terms) s += membership(t, x);
    EXPECT_NEAR(s, 1.0, 1e-12) << x;
  }
}

TEST(Fis, CornerValuesAreCentroidsOfTheExtremeTerms) {
  // (1, 1) fires only rule 36 -> "best" = triangle [13/14, 1, 1]: centroid 1 - (1/14)/3.
  EXPECT_NEAR(fis_evaluate(def(), 1.0, 1.0), 1.0 - 1.0 / 42.0, 1e-6);
  // (0, 0) fires only rule 1 -> "worst" = [0, 0, 1/14]: centroid (1/14)/3.
  EXPECT_NEAR(fis_evaluate(def(), 0.0, 0.0), 1.0 / 42.0, 1e-6);
  // (0.6, 0.6) = average/average -> "average" (centre 6/14), symmetric triangle.
  EXPECT_NEAR(fis_evaluate(def(), 0.6, 0.6), 6.0 / 14.0, 1e-6);
}

TEST(Fis, MonotoneAlongTheDiagonal) {
  double prev = -1;
  for (int i = 0; i <= 50; ++i) {
    const double v = fis_evaluate(def(), i / 50.0, i / 50.0);
    EXPECT_GE(v, prev - 1e-9);
    prev = v;
  }
}

TEST(FisLut, NodesEqualExactAndBilinearWithinOnePercent) {
  const FisLut& lut = *FisLut::cached(def(), 257);
  for (int i = 0; i < 257; i += 32)
    for (int j = 0; j < 257; j += 16) {
      const auto a = std::uint32_t((std::int64_t(i) * kQ16One) / 256), b = std::uint32_t((std::int64_t(j) * kQ16One) / 256);
      EXPECT_NEAR(lut.lookup(a, b) / 65536.0, fis_evaluate(def(), i / 256.0, j / 256.0), 2.0 / 65536);
    }
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst = 0;
  for (int k = 0; k < 500; ++k) {
    const double a = u(rng), b = u(rng);
    const double v = lut.lookup(std::uint32_t(std::llround(a * kQ16One)), std::uint32_t(std::llround(b * kQ16One))) / 65536.0;
    worst = std::max(worst, std::fabs(v - fis_evaluate(def(), a, b)));
  }
  EXPECT_LE(worst, 0.01);
}

// The table builder's evaluation (per-term aggregate, zero intervals skipped in the centroid) against
// the step-by-step reference fis_evaluate at every node: the same Q16 value, for the shipped definition
// and for definitions with other consequent shapes and rule consequents (random, seeded).
TEST(FisLut, EveryNodeEqualsTheReferenceEvaluation) {
  auto expect_nodes_equal = [](const FisDefinition& d, int size, const char* what) {
    const FisLut lut(d, size);
    int differ = 0;
    for (int i = 0; i < size; ++i)
      for (int j = 0; j < size; ++j) {
        const double v = fis_evaluate(d, static_cast<double>(i) / (size - 1), static_cast<double>(j) / (size - 1));
        const auto want = static_cast<std::uint32_t>(std::llround(std::clamp(v, 0.0, 1.0) * kQ16One));
        differ += lut.table()[std::size_t(i) * std::size_t(size) + std::size_t(j)] != want;
      }
    EXPECT_EQ(differ, 0) << what;
  };
  expect_nodes_equal(def(), 33, "shipped definition");
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(-0.03, 0.03);
  std::uniform_int_distribution<int> term(0, static_cast<int>(def().out.terms.size()) - 1);
  for (int trial = 0; trial < 3; ++trial) {
    FisDefinition d = def();
    d.output_points = 301 + 100 * trial;  // other sample grids: crossings off and on the grid
    for (auto& t : d.out.terms) {          // consequents moved and widened, order within each kept
      const double shift = jitter(rng), widen = 1.0 + 4.0 * std::fabs(jitter(rng));
      const double mid = 0.5 * (t.params.front() + t.params.back());
      for (double& p : t.params) p = std::clamp(mid + (p - mid) * widen + shift, 0.0, 1.0);
      if (t.mf == "trimf" && !(t.params[0] < t.params[1] || t.params[1] < t.params[2])) t.params = {0.0, 0.5, 1.0};
    }
    for (auto& r : d.rules) r.out = term(rng);
    expect_nodes_equal(d, 17, "perturbed definition");
  }
}

TEST(FisLut, ExtremesAndClamping) {
  const FisLut lut(def(), 256);
  EXPECT_EQ(lut.lookup(kQ16One, kQ16One), lut.table().back());
  EXPECT_EQ(lut.lookup(0, 0), lut.table().front());
  EXPECT_EQ(lut.lookup(kQ16One + 5000, kQ16One), lut.table().back());
}

}  // namespace
}  // namespace fs
