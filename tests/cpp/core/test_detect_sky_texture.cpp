// Sky texture test (session 8, docs/detection.md "(b) Texture"): a sky-coloured surface with texture is not
// sky; the smooth sky beside it stays sky up to its edge. Fast box-sum version against a direct scalar
// reference on a random image of an awkward size.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>

#include "detect_reference.hpp"
#include "fuzzystereo/detect.hpp"

namespace fs {
namespace {

TEST(DetectSkyTexture, FastMatchesReferenceOnRandomImage) {
  std::mt19937 rng(7);
  ImageRgb8 img(37, 23);
  for (auto& c : img.data) {
    const int v = int(rng() % 60);
    c = Rgb8{std::uint8_t(80 + v), std::uint8_t(120 + (rng() % 4 == 0 ? v : 0)), std::uint8_t(200)};
  }
  for (int r : {1, 2, 3})
    for (double t : {2.0, 6.0, 15.0})
      for (int rows : {23, 11, 0}) {
        const ImageU8 a = detect::textured_mask(img, rows, r, t), b = ref::textured_mask(img, rows, r, t);
        ASSERT_EQ(a.data, b.data) << "r " << r << " t " << t << " rows " << rows;
      }
}

TEST(DetectSkyTexture, TexturedSkyColouredFaceIsNotSky) {
  // 40x30: columns 0..19 a smooth blue sky (a 1-level-per-row gradient), columns 20..39 a blue checkerboard
  // face (two blues, both inside the blue HSV range; luma 143 / 87).
  ImageRgb8 img(40, 30);
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x)
      img.at(x, y) = x < 20 ? Rgb8{100, 150, std::uint8_t(220 - y)}
                            : ((x + y) % 2 ? Rgb8{100, 150, 220} : Rgb8{60, 90, 140});
  ImageI16 disp(40, 30, kInvalidDisp);
  DetectParams p;
  p.sky_max_texture = 0.0;  // colour only (the paper's rule): everything is sky
  ImageU8 m = detect::sky_mask(img, disp, 30, p);
  EXPECT_EQ(m.at(5, 10), 1);
  EXPECT_EQ(m.at(30, 10), 1);
  p.sky_max_texture = 6.0;
  p.sky_texture_radius = 2;
  m = detect::sky_mask(img, disp, 30, p);
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 20; ++x) EXPECT_EQ(m.at(x, y), 1) << x << "," << y;   // sky up to the face's edge
    for (int x = 20; x < 40; ++x) EXPECT_EQ(m.at(x, y), 0) << x << "," << y;  // the face is not sky
  }
  // Without the erosion the two sky columns beside the face (18, 19) would be textured: their windows reach it.
  const ImageU8 t = detect::textured_mask(img, 30, 2, 6.0);
  EXPECT_EQ(t.at(19, 15), 0);
  EXPECT_EQ(t.at(20, 15), 1);
  p.sky_max_texture = 60.0;  // above the checkerboard's std (28): sky again
  EXPECT_EQ(detect::sky_mask(img, disp, 30, p).at(30, 10), 1);
}

}  // namespace
}  // namespace fs
