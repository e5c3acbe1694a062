// detail::fbm (octaves by power-of-two scaling, per-thread lattice cache) against
// detail::fbm_reference (the plain per-octave loop): bit-identical on pixel-row-like walks, random
// jumps, interleaved seeds (cache collisions), every octave count and footprints from 0 to huge.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <limits>
#include <random>

#include "sim_internal.hpp"

namespace {

using fs::sim::detail::fbm;
using fs::sim::detail::fbm_reference;

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(SimNoiseFast, FbmBitIdenticalToReference) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double fps[] = {0.0, 1e-4, 0.003, 0.02, 0.1, 0.7, 5.0, 1e300, std::numeric_limits<double>::infinity()};
  const double wls[] = {0.04, 0.12, 0.35, 2.0, 6.0};
  int mismatches = 0, calls = 0, nonzero = 0;
  for (int walk = 0; walk < 300; ++walk) {
    // A walk like the shaded points along an image row: small steps in a random direction, with
    // the occasional jump; 1-3 interleaved seeds so cache slots are shared and evicted.
    double x = (uni(rng) - 0.5) * 200.0, y = (uni(rng) - 0.5) * 200.0;
    const double step = std::pow(10.0, -4.0 + 4.0 * uni(rng)), dir = 6.283185307179586 * uni(rng);
    const std::uint64_t seeds[3] = {rng(), rng(), rng() % 1000};
    const double wl = wls[walk % 5], fp = fps[walk % 9];
    for (int i = 0; i < 60; ++i) {
      if (i % 17 == 16) { x = (uni(rng) - 0.5) * 1e4; y = (uni(rng) - 0.5) * 1e4; }
      x += step * std::cos(dir);
      y += step * std::sin(dir);
      const std::uint64_t seed = seeds[i % (1 + walk % 3)];
      const int octaves = 1 + (i + walk) % 6;
      const double a = fbm(x, y, seed, wl, octaves, fp), b = fbm_reference(x, y, seed, wl, octaves, fp);
      mismatches += !same_bits(a, b);
      nonzero += a != 0.0;
      ++calls;
    }
  }
  EXPECT_EQ(mismatches, 0) << "of " << calls;
  EXPECT_GT(nonzero, calls / 2);  // octaves were really evaluated
  // Exact zeros, negative zero and subnormal coordinates (the scaled path's fall-back).
  const double odd[] = {0.0, -0.0, 4.9e-324, -1e-310, 1e-300};
  for (double ox : odd)
    for (double oy : odd) EXPECT_TRUE(same_bits(fbm(ox, oy, 7, 0.35, 6, 0.01), fbm_reference(ox, oy, 7, 0.35, 6, 0.01)));
}

}  // namespace
