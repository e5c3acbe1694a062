// Helpers for the core tests: deterministic random images and a synthetic stereo pair.
#pragma once
#include <cstdint>
#include <random>

#include "fuzzystereo/image.hpp"

namespace fs::test {

inline ImageU8 random_image(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> u(0, 255);
  ImageU8 img(w, h);
  for (auto& v : img.data) v = static_cast<std::uint8_t>(u(rng));
  return img;
}

// Smooth-ish random texture: random values box-blurred once (so SLIC finds real regions).
inline ImageU8 texture_image(int w, int h, unsigned seed) {
  const ImageU8 r = random_image(w, h, seed);
  ImageU8 out(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      int s = 0, n = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          s += r.at(xx, yy);
          ++n;
        }
      out.at(x, y) = static_cast<std::uint8_t>(s / n);
    }
  return out;
}

// Right image of a fronto-parallel scene at constant disparity d: right(x) = left(x + d).
inline ImageU8 shifted_right(const ImageU8& left, int d) {
  ImageU8 out(left.width, left.height);
  for (int y = 0; y < left.height; ++y)
    for (int x = 0; x < left.width; ++x) out.at(x, y) = left.at(std::min(left.width - 1, x + d), y);
  return out;
}

}  // namespace fs::test
