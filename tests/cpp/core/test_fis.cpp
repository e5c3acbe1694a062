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

TEST(FisLut, ExtremesAndClamping) {
  const FisLut lut(def(), 256);
  EXPECT_EQ(lut.lookup(kQ16One, kQ16One), lut.table().back());
  EXPECT_EQ(lut.lookup(0, 0), lut.table().front());
  EXPECT_EQ(lut.lookup(kQ16One + 5000, kQ16One), lut.table().back());
}

}  // namespace
}  // namespace fs
